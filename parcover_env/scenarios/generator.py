"""Procedural office-like scenarios: ``generated:SEED`` wherever a scenario name is accepted.

Layout (all from one ``numpy.random.Generator`` seeded by SEED, so a seed always gives the same map):

* an entrance hall on the left (``hall_width`` x full height) where the team lines up in a
  serpentine start queue and starts facing the corridor;
* a horizontal corridor from the hall to the right wall, with rooms above and below it
  (1-4 per side, 2-8 in all), separated by thin walls;
* one door per room in the corridor wall; some large rooms get a desk block in their middle,
  kept clear of the walls, the door approach and the KPOIs;
* 1-2 KPOIs per room in its far corners / far wall (3-12 in all, the corridor's dead end is used
  when the rooms give fewer than 3);
* overhead Kinects (3.9 m, looking down, 320x240) over the start and along the corridor.

Map sides are 6-14 m. The mapping has the YAML scenario schema and is validated by
``load_scenario``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from parcover_env.errors import ConfigError

__all__ = ["Room", "Layout", "generate_layout", "generate_scenario_mapping"]

WALL = 0.1
ROBOT_RADIUS = 0.12
SPACING = 0.4
KPOI_INSET = 0.35
MIN_ROOM_WIDTH = 1.8
MIN_ROOM_DEPTH = 2.0


@dataclass(frozen=True)
class Room:
    """An axis-aligned room ``x0..x1`` x ``y0..y1`` (m) with a door in its corridor wall."""

    x0: float
    x1: float
    y0: float
    y1: float
    side: str
    """``top`` (above the corridor) or ``bottom``."""
    door: tuple[float, float]
    """Door span along x (m)."""
    kpois: tuple[tuple[float, float], ...] = ()
    desk: tuple[tuple[float, float], ...] | None = None


@dataclass(frozen=True)
class Layout:
    """A generated map before it is written as a scenario mapping."""

    seed: int
    width: float
    height: float
    hall_width: float
    corridor: tuple[float, float]
    """Corridor span along y (m)."""
    rooms: tuple[Room, ...]
    start: tuple[float, float]
    queue: tuple[tuple[float, float], ...]
    extra_kpois: tuple[tuple[float, float], ...] = ()
    kinects: tuple[dict, ...] = field(default=())

    @property
    def kpois(self) -> list[tuple[float, float]]:
        return [k for r in self.rooms for k in r.kpois] + list(self.extra_kpois)


def _r(x: float) -> float:
    return round(float(x), 2)


def _split(rng: np.random.Generator, a: float, b: float, n: int, min_width: float) -> list[float]:
    """``n + 1`` cut positions from a to b, every piece at least ``min_width`` wide."""
    extra = (b - a) - n * min_width
    widths = min_width + extra * rng.dirichlet(np.full(n, 2.0))
    return [a, *(a + np.cumsum(widths)).tolist()]


def _room(rng: np.random.Generator, x0: float, x1: float, y0: float, y1: float, side: str) -> Room:
    dw = rng.uniform(0.75, 1.0)
    lo, hi = x0 + dw / 2 + 0.2, x1 - dw / 2 - 0.2
    c = rng.uniform(lo, hi)
    far_y = y1 - KPOI_INSET if side == "top" else y0 + KPOI_INSET
    candidates = [(x0 + KPOI_INSET, far_y), (x1 - KPOI_INSET, far_y), ((x0 + x1) / 2, far_y)]
    n_k = 1 + int(rng.random() < 0.45)
    pick = rng.choice(len(candidates), size=n_k, replace=False)
    if n_k == 2 and set(pick.tolist()) >= {2} and x1 - x0 < 2.4:
        pick = np.array([0, 1])  # middle + corner too close in a narrow room: take both corners
    kpois = tuple((_r(candidates[i][0]), _r(candidates[i][1])) for i in sorted(pick.tolist()))
    desk = None
    w, d = x1 - x0, y1 - y0
    if w >= 2.3 and d >= 2.5 and rng.random() < 0.5:
        # clear of the side walls by 0.7 m, of the corridor wall (door approach) by 0.9 m and of the
        # far wall (where the KPOIs are) by 0.9 m
        bx0, bx1 = x0 + 0.7, x1 - 0.7
        by0, by1 = y0 + 0.9, y1 - 0.9
        dx = rng.uniform(0.4, min(1.0, bx1 - bx0))
        dy = rng.uniform(0.4, min(0.8, by1 - by0))
        cx = rng.uniform(bx0 + dx / 2, bx1 - dx / 2)
        cy = rng.uniform(by0 + dy / 2, by1 - dy / 2)
        desk = tuple(
            (_r(px), _r(py))
            for px, py in (
                (cx - dx / 2, cy - dy / 2),
                (cx + dx / 2, cy - dy / 2),
                (cx + dx / 2, cy + dy / 2),
                (cx - dx / 2, cy + dy / 2),
            )
        )
    return Room(_r(x0), _r(x1), _r(y0), _r(y1), side, (_r(c - dw / 2), _r(c + dw / 2)), kpois, desk)


def generate_layout(seed: int) -> Layout:
    """The office-like layout of ``seed`` (deterministic)."""
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    width = _r(rng.uniform(6.0, 14.0))
    height = _r(rng.uniform(6.0, min(12.0, width + 2.0)))
    hall = _r(rng.uniform(1.6, 2.4))
    cw = rng.uniform(1.2, 1.6)
    bottom_depth = rng.uniform(MIN_ROOM_DEPTH, height - cw - MIN_ROOM_DEPTH)
    c0, c1 = _r(bottom_depth), _r(bottom_depth + cw)
    span = width - hall
    max_per_side = int(min(4, span // MIN_ROOM_WIDTH))
    rooms: list[Room] = []
    for side, (y0, y1) in (("top", (c1, height)), ("bottom", (0.0, c0))):
        n = int(rng.integers(1, max_per_side + 1))
        cuts = _split(rng, hall, width, n, MIN_ROOM_WIDTH)
        rooms += [_room(rng, cuts[i], cuts[i + 1], y0, y1, side) for i in range(n)]
    yc = _r((c0 + c1) / 2)
    extra: list[tuple[float, float]] = []
    kpois = [k for r in rooms for k in r.kpois]
    if len(kpois) < 3:
        extra.append((_r(width - KPOI_INSET), yc))
    while len(kpois) + len(extra) > 12:  # too many: drop second KPOIs of random rooms
        i = int(rng.choice([j for j, r in enumerate(rooms) if len(r.kpois) > 1]))
        r = rooms[i]
        rooms[i] = Room(r.x0, r.x1, r.y0, r.y1, r.side, r.door, r.kpois[:1], r.desk)
        kpois = [k for r in rooms for k in r.kpois]
    if len(kpois) + len(extra) < 3:  # still short: a second KPOI in the widest room
        i = int(np.argmax([r.x1 - r.x0 if len(r.kpois) == 1 else -1 for r in rooms]))
        r = rooms[i]
        far_y = r.y1 - KPOI_INSET if r.side == "top" else r.y0 + KPOI_INSET
        other = (
            (_r(r.x1 - KPOI_INSET), _r(far_y))
            if r.kpois[0][0] < (r.x0 + r.x1) / 2
            else (_r(r.x0 + KPOI_INSET), _r(far_y))
        )
        rooms[i] = Room(r.x0, r.x1, r.y0, r.y1, r.side, r.door, (*r.kpois, other), r.desk)
    start = (_r(hall - 0.3), yc)
    m = 0.4
    queue = ((m, yc), (m, m), (_r(hall - m), m), (_r(hall - m), _r(max(m, c0 - m))))
    kinects = [
        {
            "name": "A",
            "position": [_r(hall / 2 + 0.3), yc],
            "height": 3.9,
            "yaw_deg": 90.0,
            "resolution": [320, 240],
        }
    ]
    x = hall + 2.2
    while x < width - 1.0 and len(kinects) < 4:
        if rng.random() < 0.8:
            kinects.append(
                {
                    "name": "ABCD"[len(kinects)],
                    "position": [_r(x), yc],
                    "height": 3.9,
                    "yaw_deg": 90.0,
                    "resolution": [320, 240],
                }
            )
        x += 3.9
    return Layout(
        int(seed), width, height, hall, (c0, c1), tuple(rooms), start, queue, tuple(extra), tuple(kinects)
    )


def _walls(lay: Layout) -> list[list[list[float]]]:
    c0, c1 = lay.corridor
    walls = [
        [[lay.hall_width, c1], [lay.hall_width, lay.height]],
        [[lay.hall_width, 0.0], [lay.hall_width, c0]],
    ]
    for side, y in (("top", c1), ("bottom", c0)):
        rooms = sorted((r for r in lay.rooms if r.side == side), key=lambda r: r.x0)
        x = lay.hall_width
        for r in rooms:  # corridor wall with one gap per door
            walls.append([[x, y], [r.door[0], y]])
            x = r.door[1]
        walls.append([[x, y], [lay.width, y]])
        for r in rooms[1:]:  # dividers between neighbouring rooms
            walls.append([[r.x0, r.y0], [r.x0, r.y1]])
    return [[[_r(a), _r(b)] for a, b in w] for w in walls if w[0] != w[1]]


def generate_scenario_mapping(seed_text: str, source: str = "") -> dict:
    """Scenario mapping (YAML schema) of ``generated:SEED``; SEED is a non-negative integer."""
    text = str(seed_text).strip()
    if not text.isdigit():
        raise ConfigError(
            source or f"generated:{text}",
            "",
            f"generated scenarios need an integer seed (e.g. generated:7), got '{text}'",
        )
    lay = generate_layout(int(text))
    n_rooms, kpois = len(lay.rooms), lay.kpois
    budget = 3.0 * (lay.width + lay.height) / 0.25 / 0.1  # 3x the longest plausible route at v_max
    return {
        "name": f"generated-{lay.seed}",
        "description": f"procedural office (seed {lay.seed}): {lay.width} x {lay.height} m, {n_rooms} rooms, "
        f"{len(kpois)} KPOIs, {len(lay.kinects)} Kinects",
        "map": {
            "size": [lay.width, lay.height],
            "wall_thickness": WALL,
            "walls": _walls(lay),
            "obstacles": [[list(p) for p in r.desk] for r in lay.rooms if r.desk],
        },
        "start": {"x": lay.start[0], "y": lay.start[1], "theta_deg": 0.0},
        "start_queue": [list(p) for p in lay.queue],
        "kpois": [list(k) for k in kpois],
        "kpoi_radius": 0.4,  # Min et al. Def. 1: a KPOI is covered within the robot's sensor range
        "n_robots": "auto",
        "robot": {
            "radius": ROBOT_RADIUS,
            "max_speed": 0.25,
            "max_turn_rate": 1.2,
            "height": 0.3,
            "marker_radius": 0.03,
            "sonar": {"layout": "ring", "n_beams": 16, "range_min": 0.1, "range_max": 2.5},
        },
        "kinects": [dict(k) for k in lay.kinects],
        "formation": {"spacing": SPACING, "offset": 0.08},
        "localization": "both",  # rooms lie outside the Kinects: stale leaders localize by sonar
        "physics": {"dt": 0.02, "substeps": 5},
        "episode": {"max_steps": int(min(4000, max(800, round(budget, -2))))},
    }
