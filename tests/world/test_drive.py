"""Differential drive: wheel targets, limits, lag with bounded acceleration, and the world's use of it."""

from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pytest

from parcover_env.config import DriveConfig, MapConfig, PhysicsConfig
from parcover_env.world.drive import DiffDrive, body_velocity, lag_step, wheel_targets
from parcover_env.world.map_model import MapModel
from parcover_env.world.physics import World

BOX = MapModel.from_config(MapConfig(size=(4.0, 3.0)))
CFG = DriveConfig(wheel_base=0.18, wheel_speed_max=1.0, accel_max=1.0, tau=0.1)


def test_wheel_targets_split_v_and_omega_over_the_wheel_base():
    t = wheel_targets(np.array([[0.2, 1.0], [0.0, -2.0]]), 0.18, 1.0)
    np.testing.assert_allclose(t, [[0.2 - 0.09, 0.2 + 0.09], [0.18, -0.18]], atol=1e-15)


def test_wheel_limit_scales_both_wheels_and_keeps_the_curvature():
    t = wheel_targets(np.array([[0.9, 2.0], [-0.9, 0.0], [0.9, -2.0]]), 0.18, 1.0)
    # unclipped (0.72, 1.08) and (1.08, 0.72): scaled by 1 / 1.08; (-0.9, -0.9) is within the limit
    np.testing.assert_allclose(t, [[0.72 / 1.08, 1.0], [-0.9, -0.9], [1.0, 0.72 / 1.08]], atol=1e-15)
    v, w = body_velocity(t[:1], 0.18)[0]
    assert math.isclose(w / v, 2.0 / 0.9, rel_tol=1e-12)


def test_wheel_limit_below_one_metre_per_second():
    t = wheel_targets(np.array([[0.4, 4.0]]), 0.2, 0.5)  # unclipped (0.0, 0.8): scaled by 0.5 / 0.8
    np.testing.assert_allclose(t, [[0.0, 0.5]], atol=1e-15)


def test_body_velocity_is_the_inverse_of_the_wheel_targets():
    np.testing.assert_allclose(body_velocity(np.array([[0.1, 0.3]]), 0.2), [[0.2, 1.0]], atol=1e-15)


def test_lag_step_is_acceleration_bound_far_from_the_target_and_exponential_near_it():
    dt = 0.02
    gain = 1.0 - math.exp(-dt / 0.1)
    far = lag_step(np.array([[0.0, 0.0]]), np.array([[0.3, -0.3]]), 0.1, 1.0, dt)
    np.testing.assert_allclose(far, [[0.02, -0.02]], atol=1e-15)  # 0.3 * gain = 0.054 > a dt = 0.02
    near = lag_step(np.array([[0.25, 0.0]]), np.array([[0.3, 0.05]]), 0.1, 1.0, dt)
    np.testing.assert_allclose(near, [[0.25 + 0.05 * gain, 0.05 * gain]], atol=1e-15)


def test_one_control_step_from_rest_reaches_a_third_of_full_speed():
    drive = DiffDrive(CFG, 1)
    targets = wheel_targets(np.array([[0.3, 0.0]]), CFG.wheel_base, CFG.wheel_speed_max)
    for _ in range(5):  # one control step of 5 x 0.02 s: 5 acceleration-bound increments of 0.02 m/s
        v, w = drive.advance(targets, 0.02)[0]
    assert math.isclose(v, 0.1, abs_tol=1e-12) and w == 0.0
    assert v < 0.9 * 0.3
    travel, change = drive.take_travel()
    # the body moved at the previous physics step's speed: (0 + 0.02 + 0.04 + 0.06 + 0.08) x 0.02 s
    np.testing.assert_allclose(travel, [[0.004, 0.004]], atol=1e-15)
    np.testing.assert_allclose(change, [[0.1, 0.1]], atol=1e-15)
    assert not drive.take_travel()[0].any()
    steps = 1
    while drive.wheels[0, 0] < 0.9 * 0.3:
        for _ in range(5):
            drive.advance(targets, 0.02)
        steps += 1
    assert steps == 4  # full speed within a few tenths of a second: 0.4 s


def test_world_with_drive_moves_by_the_wheel_travel_and_pickles():
    w = World(BOX, 0.15, PhysicsConfig(dt=0.02, substeps=5), np.array([[1.0, 1.5, 0.0]]), CFG)
    w.step(np.array([[0.3, 0.0]]))
    assert math.isclose(w.poses()[0, 0], 1.004, abs_tol=1e-12)
    np.testing.assert_allclose(w.drive.travel, [[0.004, 0.004]], atol=1e-15)
    w.step(np.array([[0.3, 1.0]]))
    twin, copied = pickle.loads(pickle.dumps(w)), copy.deepcopy(w)
    for world in (w, twin, copied):
        for _ in range(3):
            world.step(np.array([[0.3, 1.0]]))
    assert np.array_equal(w.poses(), twin.poses()) and np.array_equal(w.poses(), copied.poses())
    assert np.array_equal(w.drive.wheels, twin.drive.wheels)


def test_instant_drive_keeps_the_command_as_body_velocity():
    w = World(BOX, 0.15, PhysicsConfig(dt=0.02, substeps=5), np.array([[1.0, 1.5, 0.0]]),
              DriveConfig(model="instant"))
    assert w.drive is None
    w.step(np.array([[0.3, 0.0]]))
    assert math.isclose(w.poses()[0, 0], 1.0 + 0.3 * 0.08, abs_tol=1e-9)


@pytest.mark.parametrize("field,value", [("tau", 0.0), ("accel_max", -1.0), ("wheel_speed_max", 0.0),
                                         ("wheel_base", 0.0), ("tau", 11.0)])
def test_drive_config_rejects_limits_that_stop_the_robot(field, value):
    from parcover_env.errors import ConfigError

    with pytest.raises(ConfigError, match=field):
        DriveConfig(**{field: value})


def test_advance_steps_is_the_same_floats_as_repeated_advance():
    rng = np.random.default_rng(4)
    one, many = DiffDrive(CFG, 5), DiffDrive(CFG, 5)
    for _ in range(6):  # targets far (acceleration bound) and near (exponential lag) the wheels
        targets = wheel_targets(np.column_stack([rng.uniform(-0.5, 0.5, 5), rng.uniform(-3, 3, 5)]), 0.18, 1.0)
        singles = np.stack([one.advance(targets, 0.02) for _ in range(5)])
        batch = many.advance_steps(targets, 0.02, 5)
        assert batch.tobytes() == singles.tobytes()
        assert many.wheels.tobytes() == one.wheels.tobytes()
        t1, c1 = one.take_travel()
        t2, c2 = many.take_travel()
        assert t2.tobytes() == t1.tobytes() and c2.tobytes() == c1.tobytes()
        assert np.all(c1 > 0)
