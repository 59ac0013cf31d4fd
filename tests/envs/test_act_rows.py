"""The act phase on shared rows (issue 31): the per-world arrays as views of ``(K, ...)`` blocks
(:mod:`parcover_env.world.batching`, :func:`parcover_env.localization.estimator.act_rows`), the drive, odometry
and physics calls over those rows. Each block function over K = 2 worlds of different states gives what
two K = 1 calls give, and a pinned value on a hand-built case."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

import parcover_env
from parcover_env.config import DriveConfig, MapConfig, OdometryConfig, PhysicsConfig
from parcover_env.localization.estimator import PoseEstimator, act_rows, update_all
from parcover_env.sensors import onboard_kernels
from parcover_env.sensors.odometry import Odometry, measure_wheels_all
from parcover_env.world.batching import SharedRows
from parcover_env.world.drive import DiffDrive, advance_steps_all, command_steps_all, command_steps_rows, wheel_targets
from parcover_env.world.map_model import MapModel
from parcover_env.world.physics import World, step_all

BOX = MapModel.from_config(MapConfig(size=(4.0, 3.0)))


class Holder:
    def __init__(self, a, b):
        self.a, self.b = np.array(a, dtype=float), np.array(b, dtype=float)


# ---------------------------------------------------------------------------------------- shared rows
def test_shared_rows_attach_copies_values_in_and_hands_out_views():
    x, y = Holder([1.0, 2.0], [[0.5]]), Holder([3.0, 4.0], [[-1.0]])
    rows = SharedRows(2, ("a", "b"), x)
    rows.attach([x, y])
    np.testing.assert_array_equal(rows.blocks["a"], [[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_array_equal(rows.flat["b"], [[0.5], [-1.0]])  # (K N, ...) view of the block
    assert x.a is rows.views["a"][0] and y.b is rows.views["b"][1]
    rows.blocks["a"][1, 0] = 7.0  # a write to the block is a write to the world's attribute
    assert y.a.tolist() == [7.0, 4.0]
    assert rows.attached(0, x) and rows.attached(1, y) and not rows.attached(0, y)


def test_shared_rows_adopt_a_rebound_attribute_and_detach_the_previous_owner():
    x, y, z = Holder([1.0], [2.0]), Holder([3.0], [4.0]), Holder([5.0], [6.0])
    rows = SharedRows(2, ("a", "b"), x)
    rows.attach([x, y])
    y.a = np.array([9.0])  # rebound by a per-world method: adopted again, its new value kept
    assert not rows.attached(1, y)
    rows.attach([x, y])
    assert rows.blocks["a"][1, 0] == 9.0 and y.a is rows.views["a"][1]
    rows.attach([z, y])  # a new owner of row 0 (a world reset): x keeps its values in arrays of its own
    assert x.a.tolist() == [1.0] and x.b.tolist() == [2.0] and x.a is not rows.views["a"][0]
    rows.blocks["a"][0, 0] = -1.0
    assert x.a.tolist() == [1.0] and z.a.tolist() == [-1.0]
    with pytest.raises(ValueError, match=r"Holder.a: shape \(2,\), the rows hold \(1,\)"):
        rows.attach([Holder([1.0, 2.0], [0.0]), y])
    assert rows.fits(2, x) and not rows.fits(3, x) and not rows.fits(2, Holder([1.0, 2.0], [0.0]))


def _worlds(seeds, scenario="tree"):
    envs = []
    for seed in seeds:
        env = parcover_env.parallel_env(scenario)
        env.reset(seed=seed)
        envs.append(env)
    return envs


def test_act_rows_are_reused_and_a_copy_or_pickle_owns_plain_arrays():
    envs = _worlds([1, 2])
    estimators, drives = [e.estimator for e in envs], [e.world.drive for e in envs]
    rows = act_rows(estimators, drives)
    assert act_rows(estimators, drives) is rows  # attached already: the same rows, nothing copied
    assert envs[1].estimator.odometry.estimate is rows.odometry.views["estimate"][1]
    assert envs[1].world.drive.wheels is rows.drives.views["wheels"][1]
    assert envs[1].estimator.kinect_system.next_tick is rows.kinect.views["next_tick"][1]
    for twin in (copy.deepcopy(envs[1]), pickle.loads(pickle.dumps(envs[1]))):
        odometry = twin.estimator.odometry
        assert twin.estimator.act_rows is None and odometry.estimate.base is None
        np.testing.assert_array_equal(odometry.estimate, envs[1].estimator.odometry.estimate)
        assert twin.estimator.kinect_system.next_tick.base is None
    envs[1].reset(seed=5)  # a new estimator in row 1: adopted, world 0 untouched
    again = act_rows([e.estimator for e in envs], [e.world.drive for e in envs])
    assert again is rows and envs[1].estimator.odometry.estimate is rows.odometry.views["estimate"][1]
    assert envs[1].estimator.kinect_system.next_tick is rows.kinect.views["next_tick"][1]
    assert envs[0].estimator.odometry.estimate is rows.odometry.views["estimate"][0]
    envs[0].reset(seed=6)  # world 0's new estimator holds no rows yet: world 1's are found and reused
    assert act_rows([e.estimator for e in envs], [e.world.drive for e in envs]) is rows
    assert envs[0].estimator.odometry.estimate is rows.odometry.views["estimate"][0]
    one = act_rows(estimators[:1], drives[:1])
    assert one is not rows and one.kinect is None  # another K: rows of its own (K = 1: its ticks in place)


def test_act_rows_notice_any_rebound_array_after_the_quick_identity_check():
    """Once attached, act_rows checks identities only; an array a per-world method rebinds (odometry,
    estimator, drive or Kinect ticks) is still adopted: its values land in its row."""
    envs = _worlds([1, 2])
    estimators, drives = [e.estimator for e in envs], [e.world.drive for e in envs]
    rows = act_rows(estimators, drives)
    assert act_rows(estimators, drives) is rows
    rebinds = [(lambda: envs[1].estimator.odometry, "estimate", np.array([[7.0, 8.0, 0.5]] * 15),
                lambda: rows.odometry.blocks["estimate"][1]),
               (lambda: envs[0].estimator, "fix_age", np.full(15, 3.0), lambda: rows.estimators.blocks["fix_age"][0]),
               (lambda: envs[1].world.drive, "travel", np.full((15, 2), 0.25), lambda: rows.drives.blocks["travel"][1]),
               (lambda: envs[0].estimator.kinect_system, "next_tick", np.full(4, 9.5),
                lambda: rows.kinect.blocks["next_tick"][0])]
    for owner, name, value, row in rebinds:
        setattr(owner(), name, value.copy())
        assert act_rows(estimators, drives) is rows
        np.testing.assert_array_equal(row(), value)
        assert np.shares_memory(getattr(owner(), name), row())  # the owner holds its row's view again
    envs[1].estimator.odometry = copy.deepcopy(envs[1].estimator.odometry)  # a new object, same values
    envs[1].estimator.odometry.covariance[0, 0, 0] = 4.5
    act_rows(estimators, drives)
    assert rows.odometry.blocks["covariance"][1, 0, 0, 0] == 4.5


# ---------------------------------------------------------------------------------------- physics
def test_step_all_bodies_read_one_row_per_substep():
    """A robot heading along +x with body velocities 0.1, 0.2, ... 0.5 m/s over the 5 substeps moves
    by dt (0.1 + 0.2 + 0.3 + 0.4): pymunk moves a body before its velocity update, so each substep's
    row acts one substep later (a body reading one row all step would move 4 dt 0.1)."""
    physics = PhysicsConfig(dt=0.02, substeps=5)
    w = World(BOX, 0.15, physics, np.array([[1.0, 1.5, 0.0]]))
    rows = np.zeros((1, 1, 5, 2))
    rows[0, 0, :, 0] = [0.1, 0.2, 0.3, 0.4, 0.5]
    step_all([w], np.array([[[0.5, 0.0]]]), rows)
    np.testing.assert_allclose(w.poses()[0], [1.0 + 0.02 * 1.0, 1.5, 0.0], rtol=0, atol=1e-15)
    assert w.time == pytest.approx(0.1)
    step_all([w], np.array([[[0.5, 0.0]]]), rows)  # the last row of the step before acts first
    np.testing.assert_allclose(w.poses()[0, 0], 1.0 + 0.02 * 1.0 + 0.02 * 1.5, rtol=0, atol=1e-15)


@pytest.mark.parametrize("drive", [None, DriveConfig()])
def test_step_all_of_two_worlds_is_step_of_each_alone(drive):
    physics = PhysicsConfig(dt=0.02, substeps=5)
    start = [np.array([[1.0, 1.5, 0.0], [3.0, 1.0, 3.0]]), np.array([[2.0, 2.0, -1.0], [0.5, 0.5, 1.5]])]
    pair = [World(BOX, 0.15, physics, p, drive) for p in start]
    alone = [World(BOX, 0.15, physics, p, drive) for p in start]
    rng = np.random.default_rng(0)
    for _ in range(15):
        cmd = np.column_stack([rng.uniform(-0.3, 0.5, 4), rng.uniform(-2, 2, 4)]).reshape(2, 2, 2)
        step_all(pair, cmd)
        for w, c in zip(alone, cmd, strict=True):
            w.step(c)
    for a, b in zip(pair, alone, strict=True):
        np.testing.assert_array_equal(a.poses(), b.poses())
        assert a.wall_contacts.tolist() == b.wall_contacts.tolist()
    assert np.abs(pair[1].poses() - start[1]).max() > 0.1  # the worlds did move


# ---------------------------------------------------------------------------------------- drive
def test_command_steps_rows_is_command_steps_all_and_advance_steps_of_the_wheel_targets():
    cfg = DriveConfig()
    drives = [DiffDrive(cfg, 2), DiffDrive(cfg, 2)]
    drives[1].wheels[:] = [[0.1, -0.2], [0.3, 0.05]]
    drives[1].travel[:] = [[0.01, 0.02], [0.0, 0.03]]
    commands = np.array([[[0.3, 0.0], [-0.2, 1.5]], [[0.9, 4.0], [-0.25, -0.5]]])
    by_targets, by_lists = copy.deepcopy(drives), copy.deepcopy(drives)
    wheels = np.stack([d.wheels for d in drives])
    travel = np.stack([d.travel for d in drives])
    change = np.stack([d.speed_change for d in drives])
    got = command_steps_rows(cfg, wheels, travel, change, commands, 0.02, 3)
    assert got.shape == (2, 2, 3, 2)
    np.testing.assert_array_equal(got, command_steps_all(by_lists, commands, 0.02, 3))
    targets = np.stack([wheel_targets(c, cfg.wheel_base, cfg.wheel_speed_max) for c in commands])
    for k, d in enumerate(by_targets):
        alone = advance_steps_all([d], targets[k][None], 0.02, 3)[:, 0]
        np.testing.assert_array_equal(got[k], alone.transpose(1, 0, 2))
        np.testing.assert_array_equal(wheels[k], d.wheels)
        np.testing.assert_array_equal(travel[k], d.travel)
        np.testing.assert_array_equal(change[k], d.speed_change)
    # from rest towards 0.3 m/s straight: +0.02 m/s per step (1 m/s^2 for 0.02 s), v = mean of the wheels
    np.testing.assert_allclose(got[0, 0, :, 0], [0.02, 0.04, 0.06], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(got[0, 0, :, 1], [0.0, 0.0, 0.0])
    # (0.9 m/s, 4 rad/s) asks the wheels 0.9 -+ 0.36 m/s: scaled by 1 / 1.26 to wheel_speed_max 1 m/s
    np.testing.assert_allclose(targets[1, 0], [0.54 / 1.26, 1.0], rtol=0, atol=1e-15)


def test_wheel_targets_kernel_is_wheel_targets():
    from parcover_env.world.drive_kernels import wheel_targets_into

    commands = np.array([[0.3, 0.0], [0.9, 4.0], [-0.9, 4.0], [0.0, -30.0], [-2.0, 0.5], [0.0, 0.0]])
    got = np.empty((6, 2))
    wheel_targets_into(commands, 0.18, 1.0, got)
    np.testing.assert_array_equal(got, wheel_targets(commands, 0.18, 1.0))
    np.testing.assert_allclose(got[1], [0.54 / 1.26, 1.0], rtol=0, atol=1e-15)  # the larger wheel at the limit
    np.testing.assert_allclose(got[2], [-1.0, -0.54 / 1.26], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(got[3], [1.0, -1.0])  # a pure turn beyond the limit: both wheels at it
    wheel_targets_into(commands, 0.18, np.inf, got)  # no limit (the instant drive's wheels)
    np.testing.assert_allclose(got[:, 1] - got[:, 0], 0.18 * commands[:, 1], rtol=0, atol=1e-15)


# ---------------------------------------------------------------------------------------- odometry
def _odometry(poses, seed) -> Odometry:
    return Odometry(OdometryConfig(), np.array(poses, dtype=float), 0.18, np.random.default_rng(seed))


def test_wheel_odometry_rows_is_measure_wheels_plus_velocity_fix_age_and_taken_travel():
    odos = [_odometry([[0.0, 0.0, 0.0], [1.0, 2.0, 3.14]], 3), _odometry([[5.0, 1.0, -2.0], [0.5, 0.5, 0.0]], 4)]
    travel = np.array([[[0.03, 0.02], [-0.012, -0.01]], [[-0.02, 0.02], [0.0, 0.0]]])
    change = np.array([[[0.1, 0.0], [0.2, 0.1]], [[0.0, 0.3], [0.0, 0.0]]])
    alone = copy.deepcopy(odos)
    state = onboard_kernels.OdometryState(*(np.stack([getattr(o, name) for o in odos]).reshape(4, *getattr(
        odos[0], name).shape[1:]) for name in ("estimate", "covariance", "travelled", "turned", "factors",
                                                "believed_base")))
    before = state.estimate.copy()
    z = np.stack([np.random.default_rng(10 + k).standard_normal(8) for k in range(2)])
    velocity, fix_age = np.full((4, 2), np.nan), np.array([0.0, 0.5, 1.0, 0.0])
    t, c = travel.reshape(4, 2).copy(), change.reshape(4, 2).copy()
    onboard_kernels.wheel_odometry_rows(state, t, c, 0.1, z, odos[0].wheel_errors, velocity, fix_age)
    for k, o in enumerate(alone):
        est = measure_wheels_all([o], travel[k][None], change[k][None], 0.1, [np.random.default_rng(10 + k)])[0]
        rows = slice(2 * k, 2 * k + 2)
        np.testing.assert_array_equal(state.estimate[rows], est)
        np.testing.assert_array_equal(state.covariance[rows], o.covariance)
        np.testing.assert_array_equal(state.travelled[rows], o.travelled)
    step = state.estimate - before
    sign = np.sign(travel.reshape(4, 2).sum(axis=1))
    np.testing.assert_array_equal(velocity[:, 0], np.hypot(step[:, 0], step[:, 1]) * sign / 0.1)
    np.testing.assert_array_equal(velocity[:, 1], (np.pi - ((np.pi - step[:, 2]) % (2 * np.pi))) / 0.1)
    assert velocity[1, 0] < 0 < velocity[0, 0] and velocity[3, 0] == 0.0 and not np.signbit(velocity[3, 0])
    assert state.estimate[1, 2] < 0 and 0 < velocity[1, 1] < 1.0  # the heading change across pi wrapped
    np.testing.assert_allclose(fix_age, [0.1, 0.6, 1.1, 0.1], rtol=0, atol=1e-15)
    assert not t.any() and not c.any()  # the travel was taken


@pytest.mark.parametrize("many", [False, True])  # a few fixes are written row by row, more by fancy indexing
def test_update_all_of_two_worlds_applies_each_sources_fixes_to_its_own_rows(many):
    class Fixed:
        name = "test"
        covariance = np.diag([0.01, 0.02, 0.03])

        def __init__(self, fixes):
            self.out = fixes

        def reset(self, rng):
            pass

        def fixes(self, request, rng):
            return dict(self.out)

    env = parcover_env.parallel_env("tree", overrides={"observation": {"pose_source": "odometry"}})
    env.reset(seed=0)
    s, true = env.scenario, env.true_poses()
    pose = np.array([1.0, 2.0, 0.5])
    wanted = [{1: pose, 2: pose + 1, 3: pose + 2}, {0: pose + 3, 3: pose + 4}] if many else [{1: pose}, {}]
    ests = [PoseEstimator(s, true, np.random.default_rng(k), [Fixed(f)]) for k, f in enumerate(wanted)]
    for e in ests:
        e.odometry.travelled[:] = 3.0
        e.odometry.turned[:] = 2.0
        e.fix_age[:] = 4.0
    drives = [DiffDrive(s.robot.drive, len(true)) for _ in ests]
    for d in drives:
        d.travel[:] = 0.01
    commands = np.zeros((2, len(true), 2))
    update_all(ests, np.stack([true, true]), commands, drives, [0.1, 0.1], np.zeros((2, len(true)), bool),
               [np.random.default_rng(5), np.random.default_rng(6)])
    for e, fixes in zip(ests, wanted, strict=True):
        for i in range(len(true)):
            if i in fixes:
                np.testing.assert_array_equal(e.estimate[i], fixes[i])
                np.testing.assert_array_equal(e.covariance[i], Fixed.covariance)
                assert e.odometry.travelled[i] == e.odometry.turned[i] == e.fix_age[i] == 0.0
            else:
                assert e.odometry.travelled[i] > 3.0 and e.odometry.turned[i] >= 2.0
                assert e.fix_age[i] == pytest.approx(4.0 + s.physics.control_dt)
                assert not np.allclose(e.estimate[i], pose) and e.covariance[i].any()
        assert (e.velocity[:, 0] > 0).all()  # both wheels turned forwards: a forward encoder velocity
    assert not drives[0].travel.any() and not drives[1].travel.any()  # taken by the odometry
