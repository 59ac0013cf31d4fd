"""The pymunk world: unicycle kinematics, walls hold at max speed, contacts counted."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

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


def _crowded_run(compiled: bool, drive) -> tuple[np.ndarray, list, list]:
    """Six robots pushed into the walls and each other for 60 steps; poses after every step."""
    poses = np.array([[0.5, 0.5, 0.3], [0.9, 0.6, 2.9], [1.6, 1.5, 0.1], [2.0, 1.5, 3.0], [3.4, 2.5, 0.8],
                      [3.0, 2.2, -2.6]])
    w = World(BOX, 0.15, PhysicsConfig(), poses, drive)
    w.compiled = compiled
    w._build_space(poses, np.zeros((6, 3)))
    rng = np.random.default_rng(3)
    trace = []
    for _ in range(60):
        w.step(np.column_stack([rng.uniform(0.1, 0.6, 6), rng.uniform(-1.5, 1.5, 6)]))
        trace.append(w.poses())
    return np.array(trace), w.wall_contacts.tolist(), w.robot_contacts.tolist()


def test_compiled_velocity_callback_is_bit_identical_to_the_python_one():
    from parcover_env.config import DriveConfig
    from parcover_env.world import physics

    assert physics._kernels() is not None  # this pymunk build takes the compiled path
    for drive in (None, DriveConfig()):
        fast, slow = _crowded_run(True, drive), _crowded_run(False, drive)
        assert fast[0].tobytes() == slow[0].tobytes()
        assert fast[1:] == slow[1:]
        assert sum(fast[1]) > 0 and sum(fast[2]) > 0  # the run does press robots into walls and each other
        assert np.ptp(fast[0][:, :, 2]) > 1.0  # and turns them


def test_compiled_callback_follows_the_command_of_its_own_robot():
    poses = np.array([[1.0, 1.0, 0.0], [2.0, 2.0, math.pi / 2]])
    w = World(BOX, 0.15, PhysicsConfig(dt=0.02, substeps=5), poses)
    assert w._addresses is not None
    w.step(np.array([[0.5, 0.0], [0.0, 1.0]]))
    w.step(np.array([[0.5, 0.0], [0.0, 1.0]]))  # 9 substeps of motion after the one-substep delay
    p = w.poses()
    assert math.isclose(p[0, 0], 1.0 + 0.5 * 0.18, abs_tol=1e-12) and math.isclose(p[0, 1], 1.0, abs_tol=1e-12)
    assert math.isclose(p[1, 2], math.pi / 2 + 0.18, abs_tol=1e-12)
    assert math.isclose(p[1, 0], 2.0, abs_tol=1e-12) and math.isclose(p[1, 1], 2.0, abs_tol=1e-12)


def test_step_spaces_runs_the_substeps_of_each_space_in_turn():
    """Two one-robot worlds, body velocities 0.1 .. 0.5 m/s (first world) and 0.5 .. 0.1 m/s (second)
    over 5 substeps of 0.02 s: each moves by dt times the sum of its first four rows (a body moves
    before its velocity update), the floats of pymunk's ``Space.step`` five times."""
    from parcover_env.world import body_kernels, physics

    assert physics._kernels() is not None
    from pymunk._chipmunk import ffi, lib

    cfg = PhysicsConfig(dt=0.02, substeps=5)

    def pair():
        ws = [World(BOX, 0.15, cfg, np.array([[1.0, 1.5, 0.0]])), World(BOX, 0.15, cfg, np.array([[2.0, 1.0, 0.0]]))]
        rows = np.zeros((2, 5, 2))
        rows[0, :, 0] = [0.1, 0.2, 0.3, 0.4, 0.5]
        rows[1, :, 0] = [0.5, 0.4, 0.3, 0.2, 0.1]
        for w, r in zip(ws, rows, strict=True):
            body_kernels.bind_rows(w.body_addresses, r[None])
        return ws, rows

    ws, rows = pair()
    spaces = np.array([w.space_address for w in ws], dtype=np.int64)
    body_kernels.step_spaces(body_kernels.space_step_address(ffi, lib), spaces, 0.02, 5)
    assert ws[0].poses()[0, 0] == pytest.approx(1.0 + 0.02 * 1.0, abs=1e-15)
    assert ws[1].poses()[0, 0] == pytest.approx(2.0 + 0.02 * 1.4, abs=1e-15)
    ref, _ = pair()
    for w in ref:
        for _ in range(5):
            w.space.step(0.02)
    for a, b in zip(ws, ref, strict=True):
        assert a.poses().tobytes() == b.poses().tobytes()


def test_step_all_takes_the_compiled_loop_after_the_first_step_with_the_same_floats(monkeypatch):
    """Worlds stepped by :func:`step_all` (compiled substep loop from the second step on, a rebuilt
    world through pymunk's ``Space.step`` first) are bit-identical to worlds that always step
    through ``Space.step`` (kept fresh), in contact with walls and each other."""
    from parcover_env.world import body_kernels
    from parcover_env.world.physics import step_all

    looped = []  # the spaces each compiled loop stepped
    loop = body_kernels.step_spaces
    monkeypatch.setattr(body_kernels, "step_spaces", lambda fn, spaces, *a: (looped.append(len(spaces)),
                                                                               loop(fn, spaces, *a)))
    poses = np.array([[0.5, 0.5, 0.3], [0.9, 0.6, 2.9], [1.6, 1.5, 0.1], [2.0, 1.5, 3.0]])
    fast = [World(BOX, 0.15, PhysicsConfig(), p) for p in (poses, poses[::-1].copy())]
    slow = [World(BOX, 0.15, PhysicsConfig(), p) for p in (poses, poses[::-1].copy())]
    rng = np.random.default_rng(5)
    for t in range(40):
        cmd = np.stack([np.column_stack([rng.uniform(0.1, 0.6, 4), rng.uniform(-1.5, 1.5, 4)]) for _ in range(2)])
        if t == 20:  # a rebuilt space (a copy mid-episode): its first step goes through Space.step again
            fast[1] = copy.deepcopy(fast[1])
            slow[1] = copy.deepcopy(slow[1])
        looped.clear()
        step_all(fast, cmd)
        assert fast[0].loop_ready
        assert looped == ([] if t == 0 else [1] if t == 20 else [2])  # a fresh space: Space.step
        for w, c in zip(slow, cmd, strict=True):
            w._fresh = True
            step_all([w], c[None])
    for a, b in zip(fast, slow, strict=True):
        assert a.poses().tobytes() == b.poses().tobytes()
        assert a.wall_contacts.tolist() == b.wall_contacts.tolist()
        assert a.robot_contacts.tolist() == b.robot_contacts.tolist()
        assert a.time == b.time
    assert sum(fast[0].wall_contacts) + sum(fast[0].robot_contacts) > 0


def test_step_all_without_space_handles_steps_through_space_step(monkeypatch):
    """A pymunk build that does not expose its spaces' chipmunk handles: the worlds step through
    pymunk's ``Space.step`` (no compiled substep loop), with the same floats."""
    from parcover_env.world import physics
    from parcover_env.world.physics import step_all

    assert physics._kernels() is not None
    poses = np.array([[0.5, 0.5, 0.3], [0.9, 0.6, 2.9], [1.6, 1.5, 0.1]])

    def run():
        worlds = [World(BOX, 0.15, PhysicsConfig(), p) for p in (poses, poses[::-1].copy())]
        rng = np.random.default_rng(2)
        for _ in range(20):
            step_all(worlds, np.stack([np.column_stack([rng.uniform(0.1, 0.6, 3), rng.uniform(-1.5, 1.5, 3)])
                                       for _ in range(2)]))
        return worlds

    compiled = run()
    monkeypatch.setitem(physics._COMPILED, "step", None)
    plain = run()
    assert plain[0].space_address is None and compiled[0].space_address is not None
    for a, b in zip(compiled, plain, strict=True):
        assert a.poses().tobytes() == b.poses().tobytes()
        assert a.wall_contacts.tolist() == b.wall_contacts.tolist()
