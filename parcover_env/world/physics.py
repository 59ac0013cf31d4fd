"""The pymunk world: static walls and dynamic differential-drive robots.

Robots are dynamic discs with infinite moment; each physics step their velocity is set from the
commanded unicycle velocities ``(v, omega)`` inside ``body.velocity_func``, so contacts with walls
and other robots are resolved by pymunk while the robots follow their commands in free space.
(Kinematic bodies would pass through walls.) pymunk moves bodies before it calls
``velocity_func``, so a new command takes effect after one physics step (``physics.dt``), like
an actuator delay; the velocity the contact solver corrected is what moves the body. The
``velocity_func`` is a compiled C callback (:mod:`parcover_env.world.body_kernels`) that reads
each substep's body velocity from the rows ``(substeps, 2)`` :func:`step_all` points the body at
(the worlds of a batch in one call, no Python between substeps); where that is not available, a
Python callable computing the same floats from rows written before each substep. The substeps of
all worlds then run in one compiled loop that calls chipmunk's ``cpSpaceStep`` on each world's
space (:func:`~parcover_env.world.body_kernels.step_spaces`: the function pymunk's ``Space.step``
calls, without that wrapper's Python; a space's first step still goes through ``Space.step``).

With a ``DriveConfig`` of ``model: wheels`` the commands are wheel-speed targets for a
:class:`~parcover_env.world.drive.DiffDrive` (limits, lag, bounded acceleration) advanced once per
physics step; the body velocity it returns is what ``velocity_func`` applies. ``model: instant``
(or no drive) applies the commands as they are.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from operator import is_
from typing import NamedTuple

import numpy as np
import pymunk

try:  # the C setters without pymunk's Python property layers: the callback runs N x substeps times a step
    from pymunk._chipmunk import ffi as _ffi
    from pymunk._chipmunk import lib as _cp
except ImportError:  # pragma: no cover - other pymunk builds: the public properties
    _ffi = _cp = None

from parcover_env.config import DriveConfig, PhysicsConfig
from parcover_env.geometry import wrap_angle
from parcover_env.world.drive import DiffDrive, command_steps_all
from parcover_env.world.map_model import MapModel

__all__ = ["World", "poses_all", "step_all"]

_COMPILED: dict = {}


def _kernels():
    """The compiled body access (:mod:`parcover_env.world.body_kernels`), or ``None`` if this pymunk
    build's body layout is not the one it expects (then the Python callbacks run)."""
    if "k" not in _COMPILED:
        kernels = None
        if _cp is not None:
            from parcover_env.world import body_kernels

            if body_kernels.layout_matches(_ffi, _cp):
                kernels = body_kernels
                _COMPILED["fn"] = _ffi.cast("cpBodyVelocityFunc", kernels.velocity_update.address)
                _COMPILED["step"] = kernels.space_step_address(_ffi, _cp)
        _COMPILED["k"] = kernels
    return _COMPILED["k"]

def _cp_body(body: pymunk.Body):
    """The chipmunk ``cpBody*`` of a pymunk body, for the C setters and the compiled callback. pymunk
    has no public accessor for it: this is the one place that reads its private ``_body``."""
    return body._body


ROBOT, WALL = 1, 2
# World attributes rebuilt from a snapshot, never copied
_REBUILT = ("space", "bodies", "_rows", "_suppress", "_addresses", "_space_cell", "_fresh", "_bound")
_WALL_RADIUS = 0.005  # m, collision skin of the static boundary segments


class World:
    """Physics of one episode. Build a new one at every reset (pymunk caches contact state)."""

    compiled = True
    """Set the robots' velocities with the compiled callback (``False``: pymunk's Python callbacks,
    the same floats; the compiled one is used only where the body layout check passes)."""

    def __init__(self, map_model: MapModel, radius: float, physics: PhysicsConfig, poses: np.ndarray,
                 drive: DriveConfig | None = None):
        self.map = map_model
        self.radius = float(radius)
        self.physics = physics
        self.n = len(poses)
        self.time = 0.0
        self._cmd = np.zeros((self.n, 2))
        self._rows = _CommandRows(self.n)
        self.drive = DiffDrive(drive, self.n) if drive is not None and drive.model == "wheels" else None
        """The robots' wheels (``None``: commands apply instantly)."""
        self.wall_contacts = np.zeros(self.n, dtype=np.int64)
        self.robot_contacts = np.zeros(self.n, dtype=np.int64)
        self._build_space(np.asarray(poses, dtype=float), np.zeros((self.n, 3)))

    # ------------------------------------------------------------------ snapshot / rebuild
    def _build_space(self, poses: np.ndarray, velocities: np.ndarray, touching: frozenset = frozenset()) -> None:
        """A fresh pymunk space: walls, and robots at ``poses`` (N, 3) moving at ``velocities``
        (N, 3: vx, vy, omega). ``touching``: contacts already counted (not counted again when the
        fresh space reports them as beginning)."""
        physics = self.physics
        self._rows = _CommandRows(self.n)
        self._rows.values[:] = self._cmd
        self._suppress = set(touching)
        kernels = self.compiled and _kernels()
        space = pymunk.Space()
        space.gravity = (0.0, 0.0)
        space.collision_slop = physics.collision_slop
        space.iterations = 20
        for x1, y1, x2, y2 in self.map.segments:
            seg = pymunk.Segment(space.static_body, (x1, y1), (x2, y2), _WALL_RADIUS)
            seg.collision_type = WALL
            seg.friction = 0.0
            space.add(seg)
        self.bodies: list[pymunk.Body] = []
        for i, ((x, y, theta), (vx, vy, w)) in enumerate(zip(poses.tolist(), velocities.tolist(), strict=True)):
            body = pymunk.Body(1.0, math.inf)
            body.position = (x, y)
            body.angle = theta
            body.velocity = (vx, vy)
            body.angular_velocity = w
            if not kernels:
                body.velocity_func = self._velocity_func(i)
            shape = pymunk.Circle(body, self.radius)
            shape.collision_type = ROBOT
            shape.friction = 0.0
            shape.elasticity = 0.0
            shape.robot_index = i
            space.add(body, shape)
            self.bodies.append(body)
        self._addresses = np.array([int(_ffi.cast("intptr_t", _cp_body(b))) for b in self.bodies], dtype=np.int64) \
            if kernels else None
        self._space_cell = np.array([int(_ffi.cast("intptr_t", _cp.cpBodyGetSpace(_cp_body(self.bodies[0]))))],
                                    dtype=np.int64) if kernels and self.bodies and _COMPILED["step"] else None
        """The chipmunk address of the space ``(1,)``, chipmunk's own answer for a robot's body (None: it
        steps through pymunk's ``Space.step``)."""
        self._fresh = True
        """Not stepped yet: its first step goes through pymunk's ``Space.step`` (which checks the
        bodies added), the later ones through the compiled substep loop where it is available."""
        if kernels:
            kernels.bind_commands(self._addresses, self._rows.values.ctypes.data)
            for body in self.bodies:
                _cp.cpBodySetVelocityUpdateFunc(_cp_body(body), _COMPILED["fn"])
        space.on_collision(ROBOT, WALL, begin=self._on_wall)
        space.on_collision(ROBOT, ROBOT, begin=self._on_robot)
        self.space = space

    def _touching(self) -> frozenset:
        """Contacts present now: ``(i, -1)`` robot i with a wall, ``(i, j)`` robots i < j."""
        pairs = set()
        for i, body in enumerate(self.bodies):
            def visit(arbiter, i=i):
                a, b = arbiter.shapes
                other = b if a.body is self.bodies[i] else a
                j = getattr(other, "robot_index", -1)
                pairs.add((i, j) if j < 0 else (min(i, j), max(i, j)))
            body.each_arbiter(visit)
        return frozenset(pairs)

    def _snapshot(self) -> dict:
        """Everything that determines the future: our attributes, body poses and velocities, and the
        contacts in progress (pymunk's contact cache itself is not kept)."""
        state = {k: v for k, v in self.__dict__.items() if k not in _REBUILT}
        state["_poses"] = np.array([(*b.position, b.angle) for b in self.bodies], dtype=float).reshape(self.n, 3)
        state["_velocities"] = np.array([(*b.velocity, b.angular_velocity) for b in self.bodies],
                                        dtype=float).reshape(self.n, 3)
        state["_touching"] = self._touching() | frozenset(self._suppress)
        return state

    def _restore(self, state: dict) -> None:
        state = dict(state)
        poses, velocities, touching = state.pop("_poses"), state.pop("_velocities"), state.pop("_touching")
        self.__dict__.update(state)
        self._build_space(poses, velocities, touching)

    def __getstate__(self) -> dict:
        """Snapshot for pickle/deepcopy. The world itself is rebuilt from the same snapshot, so the
        original and every copy continue bit-identically, in contact or not: a rebuilt space starts
        without pymunk's contact cache (warm-start impulses), so the original must drop it too."""
        state = self._snapshot()
        self._restore(state)
        return state

    def __setstate__(self, state: dict) -> None:
        self._restore(state)

    def __deepcopy__(self, memo: dict) -> World:
        import copy

        new = World.__new__(World)
        memo[id(self)] = new
        new.__setstate__(copy.deepcopy(self.__getstate__(), memo))
        return new

    def _velocity_func(self, i: int) -> _UnicycleVelocity:
        return _UnicycleVelocity(self._rows, i)

    def _on_wall(self, arbiter: pymunk.Arbiter, space, data) -> None:
        for shape in arbiter.shapes:
            if shape.collision_type == ROBOT:
                if self._suppress and (shape.robot_index, -1) in self._suppress:
                    continue  # a contact in progress when the space was rebuilt: counted already
                self.wall_contacts[shape.robot_index] += 1

    def _on_robot(self, arbiter: pymunk.Arbiter, space, data) -> None:
        a, b = (s.robot_index for s in arbiter.shapes)
        if self._suppress and (min(a, b), max(a, b)) in self._suppress:
            return
        self.robot_contacts[a] += 1
        self.robot_contacts[b] += 1

    def step(self, commands: np.ndarray) -> None:
        """Apply ``(v, omega)`` per robot ``(N, 2)`` for one control step (all physics substeps;
        a drive advanced here): :func:`step_all` of this world alone."""
        step_all([self], np.asarray(commands, dtype=float)[None])

    def integrate(self, commands: np.ndarray, velocities: np.ndarray, stepped: bool = False) -> None:
        """The physics substeps of one control step, the body velocities of substep ``s`` being
        ``velocities[:, s]`` ``(N, substeps, 2)`` (the commands ``(N, 2)`` as given are kept).
        Part of :func:`step_all`, which binds the compiled callbacks to ``velocities`` first: call
        that. The world keeps ``velocities`` until its next step (its bodies point into them).
        ``stepped``: :func:`step_all` ran the substeps already (its compiled loop): the rest only."""
        if stepped:  # the caller ran the substeps (step_all's compiled loop): the bookkeeping only
            self._cmd = commands  # rebound, never written in place (a caller's view is kept as it is)
            self._bound = velocities
            self.time += self.physics.control_dt
            return
        self._cmd = np.array(commands, dtype=float)
        self._bound = velocities
        self._fresh = False
        dt, step = self.physics.dt, self.space.step
        if self._addresses is not None and not self._suppress:  # the compiled callbacks read their rows
            for _ in range(self.physics.substeps):
                step(dt)
        else:
            for k in range(self.physics.substeps):
                if self._addresses is None:  # pymunk's Python callbacks read the rows written here
                    self._rows.values[:] = velocities[:, k]
                step(dt)
                if self._suppress:  # only the first step of a rebuilt space re-reports contacts in progress
                    self._suppress = set()
        self.time += self.physics.control_dt

    @property
    def body_addresses(self) -> np.ndarray | None:
        """The chipmunk addresses ``(N,)`` of the robots' bodies, read by the compiled body access
        (:mod:`parcover_env.world.body_kernels`); None where pymunk's Python callbacks run."""
        return self._addresses

    @property
    def loop_ready(self) -> bool:
        """True if :func:`step_all`'s compiled substep loop may step this world's space now: it has
        the space's address and has been stepped once by ``Space.step`` since it was built (which
        also leaves the contacts in progress at a rebuild uncounted)."""
        return self._space_cell is not None and not self._fresh

    @property
    def space_address(self) -> int | None:
        """The chipmunk address of the world's space, stepped by the compiled substep loop
        (:func:`~parcover_env.world.body_kernels.step_spaces`); None where pymunk's Python callbacks run."""
        return None if self._space_cell is None else int(self._space_cell[0])

    def poses(self) -> np.ndarray:
        """Ground-truth poses ``(N, 3)``: x, y (m), theta (rad, wrapped to (-pi, pi])."""
        out = np.empty((self.n, 3))
        if self._addresses is not None:
            _kernels().read_poses(self._addresses, out)  # the angles wrapped there
            return out
        for i, b in enumerate(self.bodies):
            out[i, 0], out[i, 1] = b.position
            out[i, 2] = b.angle
        out[:, 2] = wrap_angle(out[:, 2])
        return out


def poses_all(worlds: Sequence[World]) -> np.ndarray:
    """Ground-truth poses ``(K, N, 3)`` of ``K`` worlds of ``N`` robots each (:meth:`World.poses` of
    each, the same floats): the bodies of all worlds read in one compiled call when every world
    uses the compiled body access."""
    if len(worlds) == 1:
        return worlds[0].poses()[None]
    flat = _flat_addresses(worlds)
    if flat is None:
        return np.stack([w.poses() for w in worlds])
    out = np.empty((len(flat.bodies), 3))
    _kernels().read_poses(flat.bodies, out)  # the angles wrapped there
    return out.reshape(len(worlds), -1, 3)


class _Addresses(NamedTuple):
    """The chipmunk addresses of some worlds, world after world."""

    bodies: np.ndarray
    """``(K N,)`` their robots' bodies."""
    spaces: np.ndarray | None
    """``(K,)`` their spaces (None: they step through pymunk's ``Space.step``)."""


_FLAT: list = []
"""The worlds' addresses last concatenated (:class:`_Addresses`), and the body address arrays they came
from (kept alive, so compared by identity: a world's addresses change only when it rebuilds its space)."""


def _flat_addresses(worlds: Sequence[World]) -> _Addresses | None:
    """The addresses of all ``worlds`` end to end, or None if some world has none (pymunk's Python
    callbacks)."""
    addresses = [w.body_addresses for w in worlds]
    if _FLAT and len(_FLAT[0]) == len(addresses) and all(map(is_, addresses, _FLAT[0])):
        return _FLAT[1]
    if any(a is None for a in addresses):
        return None
    cells = [w.space_address for w in worlds]
    spaces = None if None in cells else np.array(cells, dtype=np.int64)
    _FLAT[:] = [addresses, _Addresses(np.concatenate(addresses), spaces)]
    return _FLAT[1]


def _one_world(world: World) -> _Addresses | None:
    """The addresses of one world (:func:`_flat_addresses` without its cache)."""
    if world.body_addresses is None:
        return None
    space = world.space_address
    return _Addresses(world.body_addresses, None if space is None else np.array([space], dtype=np.int64))


def step_all(worlds: Sequence[World], commands: np.ndarray, velocities: np.ndarray | None = None) -> None:
    """:meth:`World.step` of ``K`` worlds of ``N`` robots each (one physics configuration):
    ``commands`` ``(K, N, 2)``; ``velocities`` ``(K, N, substeps, 2)`` the body velocities of each
    substep when the caller advanced the worlds' drives already
    (:func:`~parcover_env.world.drive.command_steps_all`), None: the drives are advanced here (or the
    commands apply as they are, ``drive: instant``). The compiled callbacks of all worlds' bodies are
    pointed at their rows in one call, then the substeps of every world run in one compiled loop
    over the worlds' chipmunk spaces (:func:`~parcover_env.world.body_kernels.step_spaces`; a world's
    first step, or the first after a rebuild, goes through pymunk's ``Space.step``:
    :meth:`World.integrate`): the same floats as each world stepped alone."""
    first = worlds[0]
    physics = first.physics
    k, n = commands.shape[:2]
    if velocities is not None:  # the compiled callbacks walk through C-contiguous float64 rows
        velocities = np.ascontiguousarray(velocities, dtype=float)
    else:
        if first.drive is not None:
            velocities = command_steps_all([w.drive for w in worlds], commands, physics.dt, physics.substeps)
        else:  # the commands at every substep
            velocities = np.repeat(np.asarray(commands, dtype=float).reshape(k, n, 1, 2), physics.substeps, axis=2)
    flat = _flat_addresses(worlds) if k > 1 else _one_world(first)  # K = 1: the batches' cache left alone
    if flat is None:
        for w, v in zip(worlds, velocities, strict=True):
            if w.body_addresses is not None:
                _kernels().bind_rows(w.body_addresses, v)
        for w, c, v in zip(worlds, commands, velocities, strict=True):
            w.integrate(c, v)
        return
    kernels = _kernels()
    kernels.bind_rows(flat.bodies, velocities.reshape(k * n, *velocities.shape[2:]))
    # the others step through pymunk's Space.step
    ready = [False] * k if flat.spaces is None else [w.loop_ready for w in worlds]
    spaces = flat.spaces if all(ready) else flat.spaces[np.array(ready, dtype=bool)] if any(ready) else ()
    if len(spaces):
        kernels.step_spaces(_COMPILED["step"], spaces, physics.dt, physics.substeps)
    for w, c, v, stepped in zip(worlds, commands, velocities, ready, strict=True):
        w.integrate(c, v, stepped)


class _CommandRows:
    """The body velocity commands ``(n, 2)`` (v m/s, omega rad/s) applied at the next physics
    substep, shared by the world and its callbacks. Written in place: the compiled callback holds
    the address of each row."""

    __slots__ = ("values",)

    def __init__(self, n: int):
        self.values = np.zeros((n, 2))

    def __getstate__(self):
        return self.values

    def __setstate__(self, state) -> None:
        self.values = state


class _UnicycleVelocity:
    """``body.velocity_func`` of robot ``i``: velocity from the shared commands (``_CommandRows``).

    A module-level callable (not a closure) so that a ``World`` survives ``pickle`` and
    ``copy.deepcopy``; the commands stay shared with the world through pickle's memo.
    """

    __slots__ = ("cmd", "i")

    def __init__(self, cmd: _CommandRows, i: int):
        self.cmd, self.i = cmd, i

    def __getstate__(self):
        return self.cmd, self.i

    def __setstate__(self, state) -> None:
        self.cmd, self.i = state

    def __call__(self, body: pymunk.Body, gravity, damping, dt) -> None:
        v, w = self.cmd.values[self.i].tolist()
        if _cp is None:  # pragma: no cover
            a = body.angle
            body.velocity = (v * math.cos(a), v * math.sin(a))
            body.angular_velocity = w
            return
        b = _cp_body(body)
        a = _cp.cpBodyGetAngle(b)
        _cp.cpBodySetVelocity(b, (v * math.cos(a), v * math.sin(a)))
        _cp.cpBodySetAngularVelocity(b, w)
