"""The act phase on the (K, N) axis: each block function over K = 2 worlds of different states gives
what two K = 1 calls give (the same floats), and a pinned value on a hand-built case."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

import parcover_env
from parcover_env.config import DriveConfig, MapConfig, OdometryConfig, PhysicsConfig
from parcover_env.errors import ActionError
from parcover_env.sensors.odometry import Odometry, measure_wheels_all
from parcover_env.sim import act_phase
from parcover_env.sim.act_phase import to_commands, to_commands_all
from parcover_env.world.drive import DiffDrive, advance_steps_all, take_travel_all
from parcover_env.world.map_model import MapModel
from parcover_env.world.physics import World, poses_all

AGENTS = ["robot_0", "robot_1"]


def _joint(values) -> dict:
    return {a: np.array(v, dtype=np.float32) for a, v in zip(AGENTS, values, strict=True)}


def test_to_commands_all_is_to_commands_per_world_and_pinned():
    acts = [_joint([[0.5, -0.25], [2.0, 1.0]]), _joint([[-1.0, 0.125], [0.0, -3.0]])]
    got = to_commands_all(acts, [AGENTS, AGENTS], 0.3, 2.0)
    assert got.shape == (2, 2, 2)
    for k in range(2):
        np.testing.assert_array_equal(got[k], to_commands(acts[k], AGENTS, 0.3, 2.0))
    # clipped to [-1, 1], then v times max_speed and omega times max_turn_rate
    np.testing.assert_array_equal(got, [[[0.15, -0.5], [0.3, 2.0]], [[-0.3, 0.25], [0.0, -2.0]]])
    wide = to_commands_all([_joint([[0.5, 0.5, 1.0], [0.0, 0.0, -1.0]])], [AGENTS], 0.3, 2.0, width=3)
    np.testing.assert_array_equal(wide[0], [[0.15, 1.0, 1.0], [0.0, 0.0, -1.0]])


@pytest.mark.parametrize("bad, message", [
    ({"robot_0": np.array([np.nan, 0.0])}, "missing actions"),
    ({"robot_0": np.array([np.nan, 0.0]), "robot_1": np.zeros(2)}, "robot_0: action contains NaN"),
    ({"robot_0": np.zeros(3), "robot_1": np.zeros(2)}, "robot_0: action must have shape (2,)"),
])
def test_to_commands_all_raises_to_commands_error_of_the_bad_world(bad, message):
    good = _joint([[0.0, 0.0], [0.0, 0.0]])
    with pytest.raises(ActionError) as block:
        to_commands_all([good, bad], [AGENTS, AGENTS], 0.3, 2.0)
    with pytest.raises(ActionError) as alone:
        to_commands(bad, AGENTS, 0.3, 2.0)
    assert str(block.value) == str(alone.value) and message in str(block.value)


def test_to_commands_all_of_an_action_block_is_that_of_its_dicts_and_pinned():
    block = np.array([[[0.5, -0.25], [2.0, 1.0]], [[-1.0, 0.125], [0.0, -3.0]]], dtype=np.float32)
    got = to_commands_all(block, [AGENTS, AGENTS], 0.3, 2.0)
    dicts = [_joint(block[0]), _joint(block[1])]
    np.testing.assert_array_equal(got, to_commands_all(dicts, [AGENTS, AGENTS], 0.3, 2.0))
    np.testing.assert_array_equal(got, [[[0.15, -0.5], [0.3, 2.0]], [[-0.3, 0.25], [0.0, -2.0]]])
    assert block[0, 1, 0] == 2.0  # the caller's block is not clipped in place, float32 ...
    wide = block.astype(float)
    to_commands_all(wide, [AGENTS, AGENTS], 0.3, 2.0)
    assert wide[0, 1, 0] == 2.0  # ... nor float64
    wide = to_commands_all(np.array([[[0.5, 0.5, 1.0], [0.0, 0.0, -1.0]]]), [AGENTS], 0.3, 2.0, width=3)
    np.testing.assert_array_equal(wide[0], [[0.15, 1.0, 1.0], [0.0, 0.0, -1.0]])


@pytest.mark.parametrize("block, message", [
    (np.array([[[0.0, 0.0], [0.0, 0.0]], [[np.inf, 0.0], [0.0, 0.0]]]), "robot_0: action contains NaN or inf"),
    (np.array([[[0.0, 0.0], [0.0, 0.0]], [[0.0, 0.0], [0.0, np.nan]]]), "robot_1: action contains NaN or inf"),
    (np.zeros((2, 2, 3)), "robot_0: action must have shape (2,)"),
    (np.zeros((2, 2, 2), dtype=complex), "robot_0: action is not numeric"),
    (np.zeros((2, 2, 2), dtype=bool), "robot_0: action is not numeric"),
    (np.zeros((3, 2, 2)), "expected an array (2, 2, 2) (worlds, agents, action), got shape (3, 2, 2)"),
])
def test_to_commands_all_of_a_bad_block_raises_the_bad_agents_error(block, message):
    with pytest.raises(ActionError) as err:
        to_commands_all(block, [AGENTS, AGENTS], 0.3, 2.0)
    assert message in str(err.value)


def test_advance_steps_all_is_advance_steps_per_drive_and_pinned():
    cfg = DriveConfig()
    a, b = DiffDrive(cfg, 2), DiffDrive(cfg, 2)
    b.wheels[:] = [[0.1, -0.2], [0.3, 0.05]]
    b.travel[:] = [[0.01, 0.02], [0.0, 0.03]]
    targets = np.array([[[0.3, 0.3], [-0.2, 0.1]], [[0.0, 0.4], [0.3, 0.3]]])
    alone = [copy.deepcopy(a), copy.deepcopy(b)]
    got = advance_steps_all([a, b], targets, 0.02, 2)
    assert got.shape == (2, 2, 2, 2)
    for k, (d, ref) in enumerate(zip([a, b], alone, strict=True)):
        np.testing.assert_array_equal(got[:, k], ref.advance_steps(targets[k], 0.02, 2))
        for name in ("wheels", "travel", "speed_change"):
            np.testing.assert_array_equal(getattr(d, name), getattr(ref, name))
    # from rest towards 0.3 m/s: the lag asks 0.3 (1 - e^-0.2) = 0.054 m/s, clipped to 1 m/s^2 * 0.02 s
    np.testing.assert_allclose(got[:, 0, 0], [[0.02, 0.0], [0.04, 0.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.travel[0], [0.02 * 0.02] * 2, rtol=0, atol=1e-15)  # 0 m/s, then 0.02 m/s
    np.testing.assert_allclose(a.speed_change[0], [0.04, 0.04], rtol=0, atol=1e-15)


def test_take_travel_all_is_take_travel_per_drive_and_pinned():
    a, b = DiffDrive(DriveConfig(), 2), DiffDrive(DriveConfig(), 2)
    a.travel[:] = [[0.01, 0.02], [0.0, -0.03]]
    b.travel[:] = [[0.5, 0.25], [0.125, 0.0]]
    b.speed_change[:] = [[0.1, 0.0], [0.0, 0.2]]
    alone = [copy.deepcopy(a).take_travel(), copy.deepcopy(b).take_travel()]
    travel, change = take_travel_all([a, b])
    np.testing.assert_array_equal(travel, [alone[0][0], alone[1][0]])
    np.testing.assert_array_equal(change, [alone[0][1], alone[1][1]])
    np.testing.assert_array_equal(travel[1], [[0.5, 0.25], [0.125, 0.0]])
    np.testing.assert_array_equal(change[1], [[0.1, 0.0], [0.0, 0.2]])
    for d in (a, b):  # taken: the next step starts from zero
        assert not d.travel.any() and not d.speed_change.any()


def test_poses_all_is_poses_per_world_and_pinned(monkeypatch):
    box = MapModel.from_config(MapConfig(size=(4.0, 3.0)))
    physics = PhysicsConfig(dt=0.02, substeps=5)
    a = World(box, 0.15, physics, np.array([[1.0, 1.5, 0.0], [3.0, 1.0, 3.0]]))
    b = World(box, 0.15, physics, np.array([[2.0, 2.0, -1.0], [0.5, 0.5, 1.5]]))
    a.step(np.array([[0.3, 0.0], [0.0, 2.0]]))  # robot 1 turns past pi: the heading wraps
    b.step(np.array([[0.0, 0.0], [0.2, -0.5]]))
    got = poses_all([a, b])
    np.testing.assert_array_equal(got, [a.poses(), b.poses()])
    np.testing.assert_array_equal(poses_all([b])[0], b.poses())
    np.testing.assert_allclose(got[0, 0], [1.0 + 0.3 * 0.08, 1.5, 0.0], rtol=0, atol=1e-12)  # one substep late
    np.testing.assert_allclose(got[0, 1], [3.0, 1.0, 3.0 + 0.16 - 2 * math.pi], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got[1, 0], [2.0, 2.0, -1.0])
    monkeypatch.setattr(World, "compiled", False)  # pymunk's Python bodies: the same floats
    slow = World(box, 0.15, physics, np.array([[1.0, 1.5, 0.0], [3.0, 1.0, 3.0]]))
    slow.step(np.array([[0.3, 0.0], [0.0, 2.0]]))
    np.testing.assert_array_equal(poses_all([slow, b]), got)


def _odometry(poses, rng=None) -> Odometry:
    return Odometry(OdometryConfig(), np.array(poses, dtype=float), 0.18, rng)


def test_measure_wheels_all_is_measure_wheels_per_odometry():
    a = _odometry([[0.0, 0.0, 0.0], [1.0, 2.0, 1.0]], np.random.default_rng(3))
    b = _odometry([[5.0, 1.0, -2.0], [0.5, 0.5, 3.0]], np.random.default_rng(4))
    b.covariance[:] = 0.01 * np.eye(3)
    travel = np.array([[[0.03, 0.02], [0.0, 0.01]], [[-0.02, 0.02], [0.03, 0.03]]])
    change = np.array([[[0.1, 0.0], [0.2, 0.1]], [[0.0, 0.3], [0.0, 0.0]]])
    alone = [copy.deepcopy(a), copy.deepcopy(b)]
    rngs = [np.random.default_rng(10), np.random.default_rng(11)]
    est = measure_wheels_all([a, b], travel, change, 0.1, rngs)
    np.testing.assert_array_equal(est, [a.estimate, b.estimate])
    for k, (o, ref) in enumerate(zip([a, b], alone, strict=True)):
        ref.measure_wheels(travel[k], change[k], 0.1, np.random.default_rng(10 + k))
        for name in ("estimate", "covariance", "travelled", "turned"):
            np.testing.assert_array_equal(getattr(o, name), getattr(ref, name))
    check = np.random.default_rng(10)
    check.standard_normal(8)  # each generator drew its 4 N normals, no more
    assert rngs[0].random() == check.random()


def test_measure_wheels_all_pinned_without_errors():
    cfg = OdometryConfig(wheel_variance=0.0, slip_accel=0.0, slip_turn=0.0, covariance_wheel_variance=0.0)
    a = Odometry(cfg, np.zeros((2, 3)), 0.18)  # no generator: no systematic errors
    b = Odometry(cfg, np.array([[1.0, 1.0, math.pi / 2], [0.0, 0.0, 0.0]]), 0.18)
    travel = np.array([[[0.1, 0.1], [0.0, 0.018]], [[0.05, 0.05], [0.0, 0.0]]])
    measure_wheels_all([a, b], travel, np.zeros_like(travel), 0.1, [np.random.default_rng(0)] * 2)
    np.testing.assert_allclose(a.estimate, [[0.1, 0.0, 0.0], [0.009 * math.cos(0.05), 0.009 * math.sin(0.05), 0.1]],
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(b.estimate, [[1.0, 1.05, math.pi / 2], [0.0, 0.0, 0.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.travelled, [0.1, 0.009], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.turned, [0.0, 0.1], rtol=0, atol=1e-15)
    assert not a.covariance.any() and not b.covariance.any()


def _envs(scenario: str, seeds, overrides=None):
    envs = []
    for seed in seeds:
        env = parcover_env.parallel_env(scenario, overrides=overrides)
        env.reset(seed=seed)
        envs.append(env)
    return envs


SCAN = {"observation": {"scan": {"enabled": True}}}


@pytest.mark.parametrize("scenario, overrides", [("tree", None), ("office", SCAN)])
def test_act_of_two_worlds_is_act_of_each_alone(scenario, overrides):
    """Drive, physics, odometry, Kinect fixes (and the scan fixes) of K = 2 worlds of different
    states: the same floats as each world acting alone (the actions as dicts, or as one block)."""
    batch = _envs(scenario, [1, 2], overrides)
    alone = [copy.deepcopy(w) for w in batch]
    rng = np.random.default_rng(0)
    width = batch[0].action_space(batch[0].agents[0]).shape[0]
    fixed = 0
    for step in range(25):
        block = rng.uniform(-1, 1, (2, len(batch[0].agents), width)).astype(np.float32)
        actions = [dict(zip(w.agents, rows, strict=True)) for w, rows in zip(batch, block, strict=True)]
        before, true, _ = act_phase.act(batch, block if step % 2 else actions)
        for k, w in enumerate(alone):
            b1, t1 = w.act(dict(actions[k]))
            np.testing.assert_array_equal(before[k], b1)
            np.testing.assert_array_equal(true[k], t1)
            np.testing.assert_array_equal(batch[k].estimate, w.estimate)
            np.testing.assert_array_equal(batch[k].estimator.covariance, w.estimator.covariance)
            np.testing.assert_array_equal(batch[k].estimator.velocity, w.estimator.velocity)
            np.testing.assert_array_equal(batch[k].estimator.fix_age, w.estimator.fix_age)
            np.testing.assert_array_equal(batch[k].commands, w.commands)
            if w.kinects is not None:
                assert batch[k].kinects.last_fixes.keys() == w.kinects.last_fixes.keys()
                fixed += len(w.kinects.last_fixes)
            assert batch[k].np_random.random() == w.np_random.random()  # the same draws, in order
    assert scenario != "tree" or fixed > 0  # the Kinects did fix leaders on the way
