"""Sensor faults as scenario options: Kinect frames dropped at ``drop_rate``, sonar readings replaced
by garbage at ``garbage_rate``. The expert keeps running (odometry when no Kinect fix arrives), the
observations stay finite and in bounds, and the episode metrics show the degradation."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env as pe
from parcover_env.config.typed import to_mapping
from parcover_env.expert import expert_for

STEPS = 300


def _kinect_overrides(name: str, drop: float) -> dict:
    """Overrides replacing every Kinect of scenario ``name`` by the same one with ``drop_rate`` and no
    mounting error (a mis-mounted Kinect's bias, ~3 cm, can exceed 30 s of odometry drift)."""
    perfect = {"mount_tilt_std_deg": 0.0, "mount_yaw_std_deg": 0.0, "mount_height_std": 0.0}
    return {"kinects": [{**to_mapping(k), **perfect, "drop_rate": drop} for k in pe.load_scenario(name).kinects]}


def _run(overrides: dict, seed: int = 0, steps: int = STEPS) -> tuple[dict, list[np.ndarray], object]:
    env = pe.parallel_env("office", overrides=overrides)
    expert = expert_for(env)
    obs, _ = env.reset(seed=seed)
    expert.reset(obs)
    ages = []
    space = env.observation_space("robot_0")
    for _ in range(steps):
        if not env.agents:
            break
        obs, *_ = env.step(expert.act(obs))
        assert all(space.contains(o) for o in obs.values())
        ages.append(env.fix_age.copy())
        assert env.map.contains(env.world.poses()[:, :2]).all()
    return env.metrics.summary(), ages, env


@pytest.fixture(scope="module")
def clean():
    return _run(_kinect_overrides("office", 0.0))


def test_all_frames_dropped_falls_back_to_odometry(clean):
    m0, ages0, env0 = clean
    m1, ages1, env1 = _run(_kinect_overrides("office", 1.0))
    dt = env1.scenario.physics.control_dt
    # no fix ever: fix_age grows by one control period per step for every robot
    np.testing.assert_allclose(ages1[-1], len(ages1) * dt, rtol=1e-9)
    assert min(a.min() for a in ages0[10:]) < dt * 1.5, "the clean run never got a Kinect fix"
    err0, err1 = m0["localization_error"], m1["localization_error"]
    assert err1 > err0, (err0, err1)
    assert m1["kpois_visited"] >= 0 and m1["steps"] == len(ages1)


def test_half_the_frames_dropped_halves_the_fixes(clean):
    _, ages0, _ = clean
    _, ages5, _ = _run(_kinect_overrides("office", 0.5))
    fixes0 = sum(int((a == 0).sum()) for a in ages0)
    fixes5 = sum(int((a == 0).sum()) for a in ages5)
    assert fixes0 > 50
    assert 0.3 * fixes0 < fixes5 < 0.7 * fixes0, (fixes0, fixes5)


def test_sonar_garbage_stays_in_range_and_expert_survives():
    clean = pe.parallel_env("office")
    noisy = pe.parallel_env("office", overrides={"robot": {"sonar": {"garbage_rate": 1.0}}})
    s = noisy.layout.slices["sonar"]
    rmax = noisy.scenario.robot.sonar.range_max
    o0, _ = clean.reset(seed=0)
    o1, _ = noisy.reset(seed=0)
    a0, a1 = o0["robot_0"][s], o1["robot_0"][s]
    assert np.all((a1 >= 0) & (a1 <= rmax)) and not np.allclose(a0, a1)
    m, _, _ = _run({"robot": {"sonar": {"garbage_rate": 1.0}}}, steps=200)
    assert m["steps"] > 0


def test_garbage_rate_fraction():
    """About garbage_rate of the readings are replaced (compare against a clean ring, same state)."""
    from parcover_env.sensors.sonar import SonarRing

    env = pe.parallel_env("office")
    env.reset(seed=0)
    base = env.scenario.robot.sonar
    poses = env.world.poses()
    seg = env.map.segments
    ring = SonarRing(type(base)(**{**base.__dict__, "garbage_rate": 0.3, "noise_std": 0.0, "noise_rel": 0.0}))
    ref = SonarRing(type(base)(**{**base.__dict__, "noise_std": 0.0, "noise_rel": 0.0}))
    rng = np.random.default_rng(0)
    clean_r = ref.measure(poses, seg, env.scenario.robot.radius, rng)
    r = env.scenario.robot.radius
    changed = np.mean([np.mean(np.abs(ring.measure(poses, seg, r, rng) - clean_r) > 1e-6)
                       for _ in range(200)])
    assert 0.2 < changed < 0.32, changed
