"""The pymunk world: unicycle kinematics, walls hold at max speed, contacts counted."""

from __future__ import annotations

import math

import numpy as np

from parcover_env.config import MapConfig, PhysicsConfig
from parcover_env.world.map_model import MapModel
from parcover_env.world.physics import World

BOX = MapModel.from_config(MapConfig(size=(4.0, 3.0)))


def test_straight_line_and_turn_follow_unicycle_kinematics():
    w = World(BOX, 0.15, PhysicsConfig(dt=0.02, substeps=5), np.array([[1.0, 1.5, 0.0]]))
    w.step(np.array([[0.3, 0.0]]))  # a command acts after one physics step (actuator delay)
    assert math.isclose(w.poses()[0, 0], 1.0 + 0.3 * 0.08, abs_tol=1e-9)
    for _ in range(10):  # then exactly 1 s at 0.3 m/s
        w.step(np.array([[0.3, 0.0]]))
    x, y, th = w.poses()[0]
    assert math.isclose(x, 1.0 + 0.3 * 1.08, abs_tol=1e-9) and math.isclose(y, 1.5, abs_tol=1e-9)
    w.step(np.array([[0.0, 0.5]]))
    th0 = w.poses()[0, 2]
    for _ in range(10):  # 1 s at 0.5 rad/s in place
        w.step(np.array([[0.0, 0.5]]))
    assert math.isclose(w.poses()[0, 2] - th0, 0.5, abs_tol=1e-9)
    assert math.isclose(w.time, 2.2)


def test_robot_driving_into_a_wall_at_max_speed_stops_at_the_wall():
    w = World(BOX, 0.15, PhysicsConfig(dt=0.02, substeps=5), np.array([[3.0, 1.5, 0.0]]))
    for _ in range(200):
        w.step(np.array([[2.0, 0.0]]))  # 4 cm per physics step, far above normal speeds
    x = w.poses()[0, 0]
    assert 3.8 < x < 4.0 - 0.15 + 0.01  # pressed against the wall, not through it
    assert w.wall_contacts[0] >= 1


def test_robot_robot_contacts_are_counted_for_both():
    poses = np.array([[1.0, 1.5, 0.0], [2.0, 1.5, math.pi]])
    w = World(BOX, 0.15, PhysicsConfig(), poses)
    for _ in range(40):
        w.step(np.array([[0.3, 0.0], [0.3, 0.0]]))
    assert w.robot_contacts.tolist() == [1, 1]
    gap = np.hypot(*(w.poses()[0, :2] - w.poses()[1, :2]))
    assert gap > 0.29  # discs do not overlap (beyond the collision slop)
