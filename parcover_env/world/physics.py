"""The pymunk world: static walls and dynamic differential-drive robots.

Robots are dynamic discs with infinite moment; each physics step their velocity is set from the
commanded unicycle velocities ``(v, omega)`` inside ``body.velocity_func``, so contacts with walls
and other robots are resolved by pymunk while the robots follow their commands in free space.
(Kinematic bodies would pass through walls.) pymunk moves bodies before it calls
``velocity_func``, so a new command takes effect after one physics step (``physics.dt``), like
an actuator delay; the velocity the contact solver corrected is what moves the body.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from parcover_env.config import PhysicsConfig
from parcover_env.world.map_model import MapModel

__all__ = ["World"]

ROBOT, WALL = 1, 2
_WALL_RADIUS = 0.005  # m, collision skin of the static boundary segments


class World:
    """Physics of one episode. Build a new one at every reset (pymunk caches contact state)."""

    def __init__(self, map_model: MapModel, radius: float, physics: PhysicsConfig, poses: np.ndarray):
        self.map = map_model
        self.radius = float(radius)
        self.physics = physics
        self.n = len(poses)
        self.time = 0.0
        self._cmd = np.zeros((self.n, 2))
        self.wall_contacts = np.zeros(self.n, dtype=np.int64)
        self.robot_contacts = np.zeros(self.n, dtype=np.int64)

        space = pymunk.Space()
        space.gravity = (0.0, 0.0)
        space.collision_slop = physics.collision_slop
        space.iterations = 20
        for x1, y1, x2, y2 in map_model.segments:
            seg = pymunk.Segment(space.static_body, (x1, y1), (x2, y2), _WALL_RADIUS)
            seg.collision_type = WALL
            seg.friction = 0.0
            space.add(seg)
        self.bodies: list[pymunk.Body] = []
        for i, (x, y, theta) in enumerate(np.asarray(poses, dtype=float)):
            body = pymunk.Body(1.0, math.inf)
            body.position = (x, y)
            body.angle = theta
            body.velocity_func = self._velocity_func(i)
            shape = pymunk.Circle(body, self.radius)
            shape.collision_type = ROBOT
            shape.friction = 0.0
            shape.elasticity = 0.0
            shape.robot_index = i
            space.add(body, shape)
            self.bodies.append(body)
        space.on_collision(ROBOT, WALL, begin=self._on_wall)
        space.on_collision(ROBOT, ROBOT, begin=self._on_robot)
        self.space = space

    def _velocity_func(self, i: int) -> _UnicycleVelocity:
        return _UnicycleVelocity(self._cmd, i)

    def _on_wall(self, arbiter: pymunk.Arbiter, space, data) -> None:
        for shape in arbiter.shapes:
            if shape.collision_type == ROBOT:
                self.wall_contacts[shape.robot_index] += 1

    def _on_robot(self, arbiter: pymunk.Arbiter, space, data) -> None:
        for shape in arbiter.shapes:
            self.robot_contacts[shape.robot_index] += 1

    def step(self, commands: np.ndarray) -> None:
        """Apply ``(v, omega)`` per robot ``(N, 2)`` for one control step (all physics substeps)."""
        self._cmd[:] = commands
        dt = self.physics.dt
        for _ in range(self.physics.substeps):
            self.space.step(dt)
        self.time += self.physics.control_dt

    def poses(self) -> np.ndarray:
        """Ground-truth poses ``(N, 3)``: x, y (m), theta (rad, wrapped to (-pi, pi])."""
        out = np.empty((self.n, 3))
        for i, b in enumerate(self.bodies):
            out[i, 0], out[i, 1] = b.position
            out[i, 2] = b.angle
        out[:, 2] = np.pi - np.mod(np.pi - out[:, 2], 2.0 * np.pi)
        return out


class _UnicycleVelocity:
    """``body.velocity_func`` of robot ``i``: velocity from the shared command array ``(N, 2)``.

    A module-level callable (not a closure) so that a ``World`` survives ``pickle`` and
    ``copy.deepcopy``; the command array stays shared with the world through pickle's memo.
    """

    __slots__ = ("cmd", "i")

    def __init__(self, cmd: np.ndarray, i: int):
        self.cmd, self.i = cmd, i

    def __getstate__(self):
        return self.cmd, self.i

    def __setstate__(self, state) -> None:
        self.cmd, self.i = state

    def __call__(self, body: pymunk.Body, gravity, damping, dt) -> None:
        v, w = self.cmd[self.i]
        body.velocity = (v * math.cos(body.angle), v * math.sin(body.angle))
        body.angular_velocity = w
