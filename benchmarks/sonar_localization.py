"""Oracle-free accuracy of the sonar localizer (Kim, Pearce & Amato Fig. 6) and of each extension.

One trial, on a known map (``--unknown``: with obstacles in the world that the map lacks):

1. A route: a subgoal drawn uniformly inside the relaxed sectors that see a feature (where the paper's
   robots localize), a via point and a start pose in free space such that both straight legs keep
   the robot radius + ``CLEARANCE_MARGIN`` from the walls and the route is ``ROUTE_LENGTH`` m long
   (the navigator's ellipse reaches its ``max_axis`` of 0.35 m after about 6 m). The robot's
   estimate starts at the truth with zero covariance (right after a fix).
2. The drive: the robot steers to the via point and the subgoal *by its odometry estimate*
   (``control.leader.go_to_goal``), through the scenario's wheel dynamics (``world.drive``); the true
   pose integrates the wheels' true motion, the estimate comes from ``sensors.odometry`` with the
   realistic ``wheels`` model (per-trial systematic E_d / scale / E_b errors, random wheel noise,
   slip) and its propagated covariance. A trial whose true end pose is not in free space (the robot
   would have touched a wall) is redrawn; the script prints how many were.
3. The prior: the odometry estimate and its position covariance (the localizer's
   ``covariance_sigmas`` ellipse, 2 sigma), the estimate's heading as the heading prior. The true
   pose is used only to simulate the scan and to score the result.
4. The measured scan: 72 readings of the realistic sonar (specular cone, multipath, noise,
   quantization, readings below range_min lost) from the true pose, drawn with the sonar's own RNG.
   The robot's turn during the scan is not simulated (the readings are at exact 5 deg steps).
   ``mismatch`` rows draw the scan from a sonar whose parameters differ from those the localizer's
   synthetic scans assume (:data:`MISMATCH`).

Rows (the same trials, priors and scans for every row): the paper's localizer alone (features of
the relaxed sectors x features of the raw and Fig. 11 filtered scan, poses near the ellipse,
synthetic-scan confirmation); the same without the Fig. 11 filter; each extension added alone
(``polish``, ``arc_fallback``, ``grid_fallback``); all of them (the default config, what the
navigator uses); then the paper's method and all extensions against the mismatched sonar.

Columns: ``fix`` = share of trials where the localizer accepts a pose (mean clipped scan error
<= ``success_error``); ``success`` = share of trials with an accepted pose within
:data:`POS_OK` m and :data:`HEAD_OK` deg of the truth; ``wrong`` = accepted poses outside that
("confidently wrong"); median and p90 of the position and heading errors of the accepted poses;
``ms med`` / ``ms p90``: CPU time of one localization (ms, median and p90 over the trials: process CPU
time, the machine may be shared). ``--reference`` adds the same for the localizer as it was before it
was compiled (``tests/references/sonar_localizer.py``: numpy, shapely, scipy) and ``same``, the trials
whose result (accepted or not, pose, error, feature, candidates) is bit-identical to the compiled one's.

``--service`` times the env's scan service instead (``localization/sonar/service.py``, :meth:`SonarFixes.match`:
the team map with the teammates at their estimates, the localizer, the unmasked match and the
pin-down test) on the scans pinned in ``tests/localization/sonar/pinned_scans.json`` (seeded
episodes; their inputs and outcomes), CPU ms per scan median / p90: over all scans with the default
localizer, over the scans that fall back to the grid (their feature poses explain nothing: the
localizer with the grid and the polish off finds no pose within ``success_error``) and the others;
then all scans with the paper's method alone, with each extension added alone, and with every
extension but the grid (:data:`SERVICE_ROWS`). Each outcome is checked against the fixture (``same``:
bit-identical pose and informativeness; the fixture holds the default's outcomes, so only the default
row must read all of them).

    PYTHONPATH=. python benchmarks/sonar_localization.py [--trials 200] [--seed 0] [--maps hallway t_room generated:1]
        [--unknown] [--reference]
    PYTHONPATH=. python benchmarks/sonar_localization.py --service
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
import zlib
from pathlib import Path

import numpy as np
import shapely

from parcover_env.config import Scenario, SonarConfig
from parcover_env.control.leader import go_to_goal
from parcover_env.expert.config import expert_config
from parcover_env.geometry import wrap_angle
from parcover_env.localization.sonar.config import SonarLocalizerConfig, sonar_localizer_config
from parcover_env.localization.sonar.known_map import known_map_features
from parcover_env.localization.sonar.localizer import localize
from parcover_env.scenarios import load_scenario
from parcover_env.sensors.odometry import Odometry
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.drive import DiffDrive, body_velocity, wheel_targets
from parcover_env.world.map_model import MapModel

POS_OK = 0.15
"""A fix is correct within this position error (m): just above the paper's 13 cm hardware error
(§4.1), which it calls "within the allowable error"."""
HEAD_OK = 10.0
"""... and within this heading error (deg)."""
ROUTE_LENGTH = (1.5, 5.0)
"""Route length between two fixes, uniform in this range (m)."""
CLEARANCE_MARGIN = 0.05
"""The route's legs keep the robot radius plus this from the walls (m)."""
WAYPOINT_REACHED = 0.05
"""A waypoint is reached when the estimate is within this of it (m)."""


def mismatched(sonar: SonarConfig) -> SonarConfig:
    """The world's sonar of the ``mismatch`` rows, chosen once before any run (not tuned): every
    parameter the localizer's synthetic scan depends on is moved across the range the literature
    gives (``shared/ALGORITHMS.md``: cone about 30 deg, echo within about 15-25 deg of the normal,
    wall material dependent, as the paper's difficulty #1 says). The localizer keeps assuming the
    scenario's sonar."""
    return dataclasses.replace(
        sonar,
        cone_deg=sonar.cone_deg - 5.0,  # 30 -> 25 deg: a narrower beam
        incidence_max_deg=sonar.incidence_max_deg + 5.0,  # 20 -> 25 deg: walls echo more obliquely
        noise_std=2.0 * sonar.noise_std,  # sigma 0.01 + 0.01 r -> 0.02 + 0.02 r (m)
        noise_rel=2.0 * sonar.noise_rel,
        garbage_rate=sonar.garbage_rate + 0.02,  # 0 -> 2 % of readings spurious (uniform in range)
    )


UNKNOWN = {  # ``--unknown``: obstacles in the world that the known map lacks (the paper's Fig. 7 test)
    "hallway": (((3.6, 0.2), (4.2, 0.2), (4.2, 0.6), (3.6, 0.6)),
                ((9.9, 3.0), (10.4, 3.0), (10.15, 3.5)),
                ((7.6, 1.5), (8.1, 1.5), (8.1, 1.9), (7.6, 1.9))),
    "t_room": (((2.9, 3.5), (3.4, 3.5), (3.4, 3.9), (2.9, 3.9)),
               ((1.25, 0.5), (1.65, 0.5), (1.45, 0.85))),
}
"""The unknown obstacles of the previous version of this benchmark, kept as they were."""

MISMATCH = "cone 30 -> 25 deg, incidence limit 20 -> 25 deg, noise sigma x2, 2 % spurious readings"


@dataclasses.dataclass(frozen=True)
class Trial:
    truth: np.ndarray
    """True pose after the drive (x, y, theta)."""
    estimate: np.ndarray
    """Odometry estimate (x, y, theta)."""
    covariance: np.ndarray
    """Odometry pose covariance (3, 3)."""
    route_length: float


def _route(free: shapely.Geometry, goal_region: shapely.Geometry, rng: np.random.Generator) -> np.ndarray:
    """Start, via and goal points ``(3, 2)``: the goal uniform in ``goal_region``, both legs inside
    ``free`` (the eroded free space), total length within :data:`ROUTE_LENGTH`."""
    x0, y0, x1, y1 = free.bounds
    gx0, gy0, gx1, gy1 = goal_region.bounds
    while True:
        g = rng.uniform((gx0, gy0), (gx1, gy1))
        if not shapely.contains_xy(goal_region, *g):
            continue
        length = rng.uniform(*ROUTE_LENGTH)
        for _ in range(200):
            v = rng.uniform((x0, y0), (x1, y1))
            leg = float(np.hypot(*(g - v)))
            if leg >= length or not free.contains(shapely.LineString([v, g])):
                continue
            ang = rng.uniform(-math.pi, math.pi)
            s = v + (length - leg) * np.array([math.cos(ang), math.sin(ang)])
            if free.contains(shapely.LineString([s, v])):
                return np.array([s, v, g])


def _drive(sc: Scenario, waypoints: np.ndarray, theta0: float, rng: np.random.Generator) -> tuple:
    """Drive through ``waypoints[1:]`` from ``waypoints[0]`` steering by the odometry estimate;
    returns (true pose, estimate, covariance)."""
    r, ph = sc.robot, sc.physics
    truth = np.array([*waypoints[0], theta0])
    odo = Odometry(r.odometry, truth[None], r.drive.wheel_base, rng)
    drive = DiffDrive(r.drive, 1)
    k, stopped = 1, 0
    for _ in range(5000):
        est = odo.estimate[0]
        command = np.zeros((1, 2))
        if k < len(waypoints):
            d = waypoints[k] - est[:2]
            if np.hypot(*d) < WAYPOINT_REACHED:
                k += 1
                continue
            c, s = math.cos(est[2]), math.sin(est[2])
            command[0] = go_to_goal(np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]), r.max_speed,
                                    r.max_turn_rate)
        elif np.abs(drive.wheels).max() < 1e-3:
            stopped += 1
            if stopped > 1:
                break
        targets = wheel_targets(command, r.drive.wheel_base, r.drive.wheel_speed_max)
        for _ in range(ph.substeps):  # the body moves at the wheels' current speeds, then they follow
            v, w = body_velocity(drive.wheels, r.drive.wheel_base)[0]
            mid = truth[2] + 0.5 * w * ph.dt
            truth += (v * ph.dt * math.cos(mid), v * ph.dt * math.sin(mid), w * ph.dt)
            drive.advance(targets, ph.dt)
        travel, change = drive.take_travel()
        odo.measure_wheels(travel, change, ph.control_dt, rng)
    truth[2] = float(wrap_angle(truth[2]))
    return truth, odo.estimate[0].copy(), odo.covariance[0].copy()


def make_trials(sc: Scenario, world: MapModel, goal_region: shapely.Geometry, n: int,
                rng: np.random.Generator) -> tuple[list[Trial], int]:
    """``n`` trials and how many drives were redrawn because the true end pose hit a wall."""
    free = world.free.buffer(-(sc.robot.radius + CLEARANCE_MARGIN))
    goals = goal_region.intersection(free)
    shapely.prepare(free)
    out, redrawn = [], 0
    while len(out) < n:
        wp = _route(free, goals, rng)
        truth, est, cov = _drive(sc, wp, rng.uniform(-math.pi, math.pi), rng)
        if not world.contains(truth[None, :2], margin=sc.robot.radius)[0]:
            redrawn += 1
            continue
        out.append(Trial(truth, est, cov, float(np.sum(np.hypot(*np.diff(wp, axis=0).T)))))
    return out, redrawn


def score(trials: list[Trial], scans: list[np.ndarray], angles: np.ndarray, known: MapModel, feats, sectors,
          params: SonarLocalizerConfig, sonar: SonarConfig, reference=None) -> dict:
    """Accuracy of ``localize`` on the trials and its CPU time per scan (ms; the process's CPU time, as
    the machine may be shared); with ``reference`` (the localizer before it was compiled), that one's
    time too and how many of its results equal the compiled one's bit for bit."""
    pos, head, fixes, good, ms, ms_ref, same = [], [], 0, 0, [], [], 0
    for tr, scan in zip(trials, scans, strict=True):
        args = (scan, angles, known, sectors, (tr.estimate[:2], tr.covariance[:2, :2]), params)
        kw = {"sonar": sonar, "features": feats, "heading": float(tr.estimate[2])}
        t0 = time.process_time()
        res = localize(*args, **kw)
        ms.append(1000 * (time.process_time() - t0))
        if reference is not None:
            t0 = time.process_time()
            old = reference(*args, **kw)
            ms_ref.append(1000 * (time.process_time() - t0))
            same += (old.success, old.error, old.candidates_tried, old.feature) == (
                res.success, res.error, res.candidates_tried, res.feature) and (
                (old.pose is None and res.pose is None) or np.array_equal(old.pose, res.pose))
        if not res.success:
            continue
        fixes += 1
        pe = float(np.hypot(*(res.pose[:2] - tr.truth[:2])))
        he = math.degrees(abs(float(wrap_angle(res.pose[2] - tr.truth[2]))))
        good += pe <= POS_OK and he <= HEAD_OK
        pos.append(pe)
        head.append(he)
    n = len(trials)

    def q(x, k):
        return float(np.percentile(x, k)) if len(x) else float("nan")

    return {"fix": fixes / n, "success": good / n, "wrong": fixes - good, "pos_med": q(pos, 50),
            "pos_p90": q(pos, 90), "head_med": q(head, 50), "head_p90": q(head, 90),
            "ms_med": q(ms, 50), "ms_p90": q(ms, 90), "ref_med": q(ms_ref, 50), "ref_p90": q(ms_ref, 90),
            "same": same}


def rows(loc: SonarLocalizerConfig) -> list[tuple[str, SonarLocalizerConfig, bool]]:
    """(label, localizer config, mismatched sonar) of each row, the paper's method first."""
    paper = loc.paper_method()
    return [("paper (Fig. 6 + Fig. 11 filter)", paper, False),
            ("paper without the Fig. 11 filter", dataclasses.replace(paper, filter=False), False),
            ("paper + polish", dataclasses.replace(paper, polish=True), False),
            ("paper + arc fallback", dataclasses.replace(paper, arc_fallback=True), False),
            ("paper + grid fallback", dataclasses.replace(paper, grid_fallback=True), False),
            ("all extensions (default)", loc, False),
            ("paper, sonar mismatch", paper, True),
            ("all extensions, sonar mismatch", loc, True)]


def run_map(name: str, trials_n: int, seed: int, unknown: bool = False, reference=None) -> None:
    sc = load_scenario(name)
    if unknown:
        if name not in UNKNOWN:
            raise SystemExit(f"--unknown: no unknown obstacles defined for {name!r} (only {sorted(UNKNOWN)})")
        sc = dataclasses.replace(sc, map=dataclasses.replace(sc.map, unknown_obstacles=UNKNOWN[name]))
    loc, sonar = sonar_localizer_config(sc), sc.robot.sonar
    sector_rule = expert_config(sc).navigator.sector_rule
    known, feats, sectors = known_map_features(sc.map, sonar.range_max, sector_rule)
    world = MapModel.from_config(sc.map, include_unknown=True)
    # one stream per purpose, seeded by (seed, map name): routes + odometry, the sonar, the mismatched sonar
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence([seed, zlib.crc32(name.encode())]).spawn(3)]
    goal_region = shapely.union_all([s.polygon for s in sectors if s.features])
    t0 = time.perf_counter()
    trials, redrawn = make_trials(sc, world, goal_region, trials_n, streams[0])
    t_drive = time.perf_counter() - t0
    ring, ring_mis = SonarRing(sonar), SonarRing(mismatched(sonar))
    scans = [ring.scan(t.truth, world.segments, None, sc.robot.radius, streams[1]) for t in trials]
    scans_mis = [ring_mis.scan(t.truth, world.segments, None, sc.robot.radius, streams[2]) for t in trials]
    prior = np.array([np.hypot(*(t.estimate[:2] - t.truth[:2])) for t in trials])
    prior_head = np.degrees(np.abs(wrap_angle(np.array([t.estimate[2] - t.truth[2] for t in trials]))))
    sig = np.array([math.sqrt(np.linalg.eigvalsh(t.covariance[:2, :2]).max()) for t in trials])
    print(f"\n{name}{' with unknown obstacles' if unknown else ''}: {trials_n} trials (seed {seed}; "
          f"{redrawn} drives redrawn: true end pose against a wall), "
          f"{len(sectors)} relaxed sectors (rule {sector_rule}), routes "
          f"{np.median([t.route_length for t in trials]):.1f} m median ({t_drive:.1f} s to drive)")
    print(f"  odometry prior: position error median {100 * np.median(prior):.1f} cm, p90 "
          f"{100 * np.percentile(prior, 90):.1f} cm; heading error median {np.median(prior_head):.2f} deg, p90 "
          f"{np.percentile(prior_head, 90):.2f} deg; 1-sigma major axis median {100 * np.median(sig):.1f} cm")
    ref_head = f" {'ref med':>8s} {'ref p90':>8s} {'same':>5s}" if reference is not None else ""
    print(f"  {'row':32s} {'fix':>6s} {'success':>8s} {'wrong':>6s} {'pos med':>8s} {'pos p90':>8s} "
          f"{'head med':>9s} {'head p90':>9s} {'ms med':>7s} {'ms p90':>7s}{ref_head}")
    for _, params, mis in rows(loc):  # untimed warm-up: numba loads its compiled kernels on the first calls
        score(trials[:2], (scans_mis if mis else scans)[:2], ring.scan_angles, known, feats, sectors, params, sonar)
    for label, params, mis in rows(loc):
        r = score(trials, scans_mis if mis else scans, ring.scan_angles, known, feats, sectors, params, sonar,
                  reference)
        ref_cols = (f" {r['ref_med']:8.2f} {r['ref_p90']:8.2f} {r['same']:5d}" if reference is not None else "")
        print(f"  {label:32s} {100 * r['fix']:5.0f}% {100 * r['success']:7.0f}% {r['wrong']:6d} "
              f"{100 * r['pos_med']:6.1f}cm {100 * r['pos_p90']:6.1f}cm {r['head_med']:7.2f}deg "
              f"{r['head_p90']:7.2f}deg {r['ms_med']:7.2f} {r['ms_p90']:7.2f}{ref_cols}")


def _reference_localize():
    """``localize`` as it was before it was compiled (numpy, shapely, scipy), kept under ``tests/references``."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from references.sonar_localizer import localize as reference

    return reference


SERVICE_FIXTURE = Path(__file__).resolve().parents[1] / "tests" / "localization" / "sonar" / "pinned_scans.json"
SERVICE_OVERRIDES = {"observation": {"scan": {"enabled": True}, "pose_source": "odometry"}}
"""The scenario overrides the pinned service scans were taken with (``tests/localization/sonar/pinned_scans.py``)."""


SERVICE_ROWS = (("paper's method (no polish, arc, grid)", {}),
                ("paper + polish", {"polish": True}),
                ("paper + arc_fallback", {"arc_fallback": True}),
                ("paper + grid_fallback", {"grid_fallback": True}),
                ("all but grid_fallback", None))
"""The service rows beside the default: the paper's method (:meth:`SonarLocalizerConfig.paper_method`), each
extension added alone, and every extension but the grid (``None``: the default with ``grid_fallback`` off)."""


def _grid_scan(svc, i: int, ranges: np.ndarray, request, inflation: float) -> bool:
    """Whether the service's localizer falls back to the grid on this scan: with the grid and the polish
    off (the localizer's error then is the feature poses' smallest), no pose within ``success_error``."""
    from parcover_env.localization.sonar.localizer import Ellipse

    others = np.delete(np.arange(len(request.estimate)), i)
    prior = request.estimate[i]
    cov = request.covariance[i] if request.covariance is not None else np.zeros((3, 3))
    pos, turn = svc.gate(cov * inflation**2)
    region = Ellipse.from_covariance(prior[:2], pos, svc.cfg.gate_sigmas)
    params = dataclasses.replace(svc.params, grid_fallback=False, polish=False)
    res = localize(ranges, svc.ring.scan_angles, svc.team_map(request.estimate[others, :2]), svc.sectors, region,
                   params, sonar=svc.ring.cfg, features=svc.features, heading=float(prior[2]), heading_tol=turn)
    return res.pose is None or res.error > svc.params.success_error


def run_service() -> None:
    """CPU ms per scan of the env's scan service on the pinned episode scans (see the module docstring)."""
    from parcover_env.localization.estimator import FixRequest
    from parcover_env.localization.sonar.service import SonarFixes

    data = json.loads(SERVICE_FIXTURE.read_text())["service"]
    scans, twins = [], {}
    for run, cases in sorted(data.items()):
        sc = load_scenario(run.split("@")[0], SERVICE_OVERRIDES)
        svc = SonarFixes(sc, MapModel.from_config(sc.map).segments, len(cases[0]["estimate"]))
        twins[id(svc)] = {}
        for label, change in SERVICE_ROWS:  # the same service with the localizer's extensions switched
            twin = twins[id(svc)][label] = SonarFixes(sc, svc.segments, len(cases[0]["estimate"]))
            twin.params = (dataclasses.replace(twin.params.paper_method(), **change) if change is not None
                           else dataclasses.replace(twin.params, grid_fallback=False))
        for c in cases:
            est = np.array(c["estimate"])
            cov = None if c["covariance"] is None else np.array(c["covariance"])
            request = FixRequest(0.0, est.copy(), est, np.zeros(len(est), bool), cov)  # the truth is never read
            scans.append((svc, c, np.array(c["ranges"]), request))
    grid = np.array([_grid_scan(svc, c["i"], r, req, c["inflation"]) for svc, c, r, req in scans])

    def timed(pick) -> tuple[np.ndarray, int]:
        ms, same = [], 0
        for svc, c, r, req in scans:
            s = pick(svc)
            t = time.process_time()
            pose, informative = s.match(c["i"], r, req, c["inflation"])
            ms.append(1e3 * (time.process_time() - t))
            want = c["pose"]
            same += informative == c["informative"] and (
                pose is None and want is None or pose is not None and want is not None
                and np.array_equal(pose, np.array(want)))
        return np.array(ms), same

    timed(lambda s: s)  # untimed warm-up: numba loads its compiled kernels on the first calls
    ms, same = timed(lambda s: s)
    print(f"env scan service (SonarFixes.match) on {len(scans)} pinned episode scans "
          f"({SERVICE_FIXTURE.name}); CPU ms per scan; same = bit-identical to the pinned outcome "
          f"(the default's; the other rows change the localizer)")
    print(f"  {'scans':50s} {'n':>4s} {'ms med':>7s} {'ms p90':>7s} {'same':>5s}")
    for label, t in (("all (default: paper + every extension)", ms),
                     ("  grid fallback (feature poses explain nothing)", ms[grid]),
                     ("  no grid fallback needed", ms[~grid])):
        med, p90 = (np.median(t), np.percentile(t, 90)) if len(t) else (math.nan, math.nan)
        print(f"  {label:50s} {len(t):4d} {med:7.2f} {p90:7.2f} {same if t is ms else '':>5}")
    for label, _ in SERVICE_ROWS:
        t, n_same = timed(lambda s, label=label: twins[id(s)][label])
        print(f"  {label:50s} {len(t):4d} {np.median(t):7.2f} {np.percentile(t, 90):7.2f} {n_same:5d}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=200, help="trials per map")
    ap.add_argument("--seed", type=int, default=0, help="seed of the routes, odometry errors and sonar noise")
    ap.add_argument("--maps", nargs="+", default=["hallway", "t_room", "generated:1"])
    ap.add_argument("--unknown", action="store_true",
                    help="put obstacles the known map lacks into the world (hallway, t_room; the paper's Fig. 7)")
    ap.add_argument("--reference", action="store_true",
                    help="also run the localizer as it was before it was compiled (tests/references/"
                         "sonar_localizer.py): its CPU ms per scan side by side, and how many results are "
                         "bit-identical ('same')")
    ap.add_argument("--service", action="store_true",
                    help="time the env's scan service on the pinned episode scans instead (ms per scan)")
    args = ap.parse_args()
    if args.service:
        run_service()
        return
    reference = _reference_localize() if args.reference else None
    print(f"success: accepted fix within {100 * POS_OK:.0f} cm and {HEAD_OK:.0f} deg of the truth; wrong: accepted "
          f"fixes outside that; errors over accepted fixes. Mismatch rows: {MISMATCH}.")
    for name in args.maps:
        run_map(name, args.trials, args.seed, args.unknown, reference)


if __name__ == "__main__":
    main()
