"""Physics faults: adversarial max-speed actions with many robots on every scenario. No robot may
leave free space or sink into a wall, robots may not overlap beyond a small contact tolerance, no
observation may hold NaN/inf or leave its Box, and robots jammed together separate again."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

import parcover_env as pe

# as many robots as placement seats around each start (placement refuses more with a ConfigError)
MANY = {"office": 8, "tree": 8, "hallway": 6, "t_room": 3}
CI_STEPS = 800
WALL_TOL = 0.1   # x radius: deepest allowed wall penetration
ROBOT_TOL = 0.25  # x radius: deepest allowed robot-robot overlap


def _adversary(env, rng: np.random.Generator, k: int) -> dict:
    """Max-speed actions; the pattern changes every 25 steps: bang-bang turns, reverse, spin,
    everybody at full speed toward the team centroid (a jam), or straight ahead into walls."""
    n = env.n_robots
    mode = (k // 25) % 5
    a = np.empty((n, 2))
    if mode == 0:
        a[:, 0], a[:, 1] = 1.0, rng.choice([-1.0, 1.0], n)
    elif mode == 1:
        a[:, 0], a[:, 1] = -1.0, rng.choice([-1.0, 0.0, 1.0], n)
    elif mode == 2:
        a[:, 0], a[:, 1] = rng.choice([-1.0, 1.0], n), 1.0
    elif mode == 3:
        a[:] = _toward(env.world.poses(), env.world.poses()[:, :2].mean(axis=0))
    else:
        a[:, 0], a[:, 1] = 1.0, 0.0
    return {f"robot_{i}": a[i] for i in range(n) if f"robot_{i}" in env.agents}


def _toward(poses: np.ndarray, target: np.ndarray, away: bool = False) -> np.ndarray:
    d = (poses[:, :2] - target) if away else (target - poses[:, :2])
    err = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - poses[:, 2])))
    return np.column_stack([np.where(np.abs(err) < 0.6, 1.0, 0.0), np.clip(3.0 * err, -1.0, 1.0)])


def _violations(env) -> tuple[float, float, bool]:
    """(worst wall penetration, worst robot overlap) in metres, and whether all centres are in free space."""
    p = env.world.poses()[:, :2]
    r = env.scenario.robot.radius
    d = shapely.distance(env.map.free.boundary, shapely.points(p))
    inside = env.map.contains(p)
    wall = float(np.max(np.where(inside, r - d, r + d)))
    gaps = np.hypot(*(p[:, None] - p[None]).transpose(2, 0, 1))
    np.fill_diagonal(gaps, np.inf)
    return max(wall, 0.0), max(float(2 * r - gaps.min()), 0.0), bool(inside.all())


def run_adversarial(name: str, steps: int, seed: int = 0) -> dict:
    env = pe.parallel_env(name, overrides={"n_robots": MANY[name]})
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    space = env.observation_space("robot_0")
    worst_wall = worst_robot = 0.0
    resets = 0
    for k in range(steps):
        if not env.agents:
            obs, _ = env.reset()
            resets += 1
        obs, rew, *_ = env.step(_adversary(env, rng, k))
        wall, robot, inside = _violations(env)
        worst_wall, worst_robot = max(worst_wall, wall), max(worst_robot, robot)
        assert inside, f"{name} step {k}: a robot centre left free space"
        for a, o in obs.items():
            assert np.all(np.isfinite(o)), f"{name} step {k}: non-finite observation for {a}"
            assert space.contains(o), f"{name} step {k}: observation of {a} outside its Box"
        assert all(np.isfinite(v) for v in rew.values()), f"{name} step {k}: non-finite reward"
    r = env.scenario.robot.radius
    assert worst_wall <= WALL_TOL * r, f"{name}: wall penetration {worst_wall:.4f} m"
    assert worst_robot <= ROBOT_TOL * r, f"{name}: robot overlap {worst_robot:.4f} m"
    return {"wall": worst_wall, "robot": worst_robot, "resets": resets}


@pytest.mark.parametrize("name", sorted(MANY))
def test_adversarial_max_speed_ci(name):
    run_adversarial(name, CI_STEPS)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(MANY))
def test_adversarial_max_speed_1e5_steps(name):
    run_adversarial(name, 100_000, seed=1)


@pytest.mark.parametrize("name", ["office", "tree"])
def test_jammed_robots_recover(name):
    """Everybody drives at full speed into the team centroid, then away from it: during the jam the
    contact solver keeps them apart (bounded overlap), afterwards they are separated again."""
    env = pe.parallel_env(name, overrides={"n_robots": MANY[name]})
    env.reset(seed=0)
    r = env.scenario.robot.radius
    centre = env.world.poses()[:, :2].mean(axis=0)
    spread0 = np.hypot(*(env.world.poses()[:, :2] - centre).T).mean()
    for _ in range(150):
        p = env.world.poses()
        env.step({f"robot_{i}": a for i, a in enumerate(_toward(p, centre))})
        assert _violations(env)[1] <= ROBOT_TOL * r
    jam = env.world.poses()[:, :2]
    spread_jam = np.hypot(*(jam - centre).T).mean()
    assert spread_jam < spread0, "the robots were not pushed together"
    assert env.world.robot_contacts.sum() > 0, "no robot-robot contact happened in the jam"
    for _ in range(60):
        p = env.world.poses()
        env.step({f"robot_{i}": a for i, a in enumerate(_toward(p, centre, away=True))})
    after = env.world.poses()[:, :2]
    gaps = np.hypot(*(after[:, None] - after[None]).transpose(2, 0, 1))
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() >= 2 * r - 1e-3, f"robots still overlap after separating: {gaps.min():.3f} m"
    assert np.hypot(*(after - centre).T).mean() > spread_jam + 0.1, "the team did not spread out again"
    moved = np.hypot(*(after - jam).T)
    assert np.all(moved > 0.05), f"robots stuck in the jam: moved {moved.round(3).tolist()}"
