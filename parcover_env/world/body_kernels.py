"""Compiled (numba) access to the robots' chipmunk bodies, the internals of
:mod:`parcover_env.world.physics` (public so that tests and other rooms may use them), which falls
back to pymunk's Python callbacks when :func:`layout_matches` is false.

pymunk calls a Python ``velocity_func`` once per body per physics substep, after it has moved the
bodies and before the contact solver. :func:`velocity_update` is the same unicycle update as a C
callback: ``v = (v_cmd cos a, v_cmd sin a)``, ``omega = omega_cmd`` with ``a`` the body angle
after the position update, the same IEEE operations as the Python callback (``math.cos``/``sin``
of the C library, no fast-math), so trajectories are bit-identical. Each body finds its command row
``(v_cmd, omega_cmd)`` through an address kept in its torque slot (a body of infinite moment,
whose velocity update is this callback, never reads its torque) and moves that address on to the
next row: :func:`bind_rows` points every body at the first of its rows ``(substeps, 2)``, one per
physics substep of the control step, so the substeps of a step need no writes from Python.

chipmunk's ``cpBody`` is opaque to pymunk's cffi layer; the slots used here follow the field order
of chipmunk's ``cpBody`` (function pointers, mass, moment, centre of gravity, position, velocity,
force, angle, angular velocity, torque). :func:`layout_matches` checks them against pymunk's own
getters before the world relies on them.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import carray, cfunc, njit, types
from numba.extending import intrinsic

from parcover_env.geometry.angle_kernels import wrap

__all__ = ["N_SLOTS", "ROW_BYTES", "layout_matches", "velocity_update", "bind_commands", "bind_rows", "read_poses",
           "step_spaces", "space_step_address"]

N_SLOTS = 17
"""8-byte slots of ``cpBody`` read or written here (up to the torque)."""
_PX, _PY, _VX, _VY, _A, _W, _T = 8, 9, 10, 11, 14, 15, 16
"""Slot indices: position, velocity, angle, angular velocity, torque (holds the command address)."""
ROW_BYTES = 16
"""Bytes of one command row ``(v_cmd, omega_cmd)`` (two float64)."""


@intrinsic
def _pointer(typingctx, address):
    """An integer address as a ``void*``."""
    sig = types.voidptr(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.voidptr))

    return sig, codegen


@intrinsic
def _call_space_step(typingctx, function, space, dt):
    """Call the C function ``void f(cpSpace *, double)`` at address ``function`` on ``space``."""
    sig = types.void(types.int64, types.int64, types.float64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.VoidType(), [ir.IntType(8).as_pointer(), ir.DoubleType()])
        target = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(target, [builder.inttoptr(args[1], ir.IntType(8).as_pointer()), args[2]])
        return context.get_dummy_value()

    return sig, codegen


@cfunc(types.void(types.voidptr), cache=True)
def velocity_update(body):
    """``cpBodyVelocityFunc`` (only the body argument is read): velocity from the body's command row;
    the body's command address then moves on to its next row (the next substep's)."""
    b = carray(body, N_SLOTS, dtype=np.float64)
    slots = carray(body, N_SLOTS, dtype=np.int64)
    address = slots[_T]
    row = carray(_pointer(address), 2, dtype=np.float64)
    v = row[0]
    a = b[_A]
    b[_VX] = v * math.cos(a)
    b[_VY] = v * math.sin(a)
    b[_W] = row[1]
    slots[_T] = address + ROW_BYTES


@njit(cache=True)
def bind_commands(bodies, commands_address):
    """Point body ``i`` (addresses ``bodies``) at row ``i`` of the C-contiguous ``(n, 2)`` float64
    command array starting at ``commands_address``."""
    for i in range(bodies.shape[0]):
        carray(_pointer(bodies[i]), N_SLOTS, dtype=np.int64)[_T] = commands_address + ROW_BYTES * i


@njit(cache=True)
def bind_rows(bodies, rows):
    """Point body ``j`` (addresses ``bodies``) at ``rows[j, 0]`` of the C-contiguous float64 command
    rows ``rows (n, substeps, 2)``: the callback then reads ``rows[j, s]`` at substep ``s``."""
    first = rows.ctypes.data
    stride = rows.shape[1] * ROW_BYTES
    for j in range(bodies.shape[0]):
        carray(_pointer(bodies[j]), N_SLOTS, dtype=np.int64)[_T] = first + stride * j


@njit(cache=True)
def read_poses(bodies, out):
    """Write ``x, y, angle`` of the bodies at addresses ``bodies`` into ``out`` ``(n, 3)``, the angle
    wrapped to (-pi, pi] (:func:`~parcover_env.geometry.angle_kernels.wrap`, the floats of
    :func:`~parcover_env.geometry.angles.wrap_angle`)."""
    for i in range(bodies.shape[0]):
        b = carray(_pointer(bodies[i]), N_SLOTS, dtype=np.float64)
        out[i, 0] = b[_PX]
        out[i, 1] = b[_PY]
        out[i, 2] = wrap(b[_A])


@njit(cache=True)
def step_spaces(step_function, spaces, dt, substeps):
    """``substeps`` steps of ``dt`` (s) of each chipmunk space at the addresses ``spaces`` in turn, by
    chipmunk's ``cpSpaceStep`` at the address ``step_function`` (what pymunk's ``Space.step`` calls;
    pymunk's Python collision callbacks run from inside it as they do there). Without the bookkeeping
    of pymunk's wrapper: only for spaces whose callbacks add or remove nothing and that have no
    post-step callbacks or bodies added since their last ``Space.step``."""
    for j in range(spaces.shape[0]):
        for _ in range(substeps):
            _call_space_step(step_function, spaces[j], dt)


def space_step_address(ffi, lib) -> int:
    """The address of chipmunk's ``cpSpaceStep`` in pymunk's cffi module ``lib`` (for :func:`step_spaces`)."""
    return int(ffi.cast("intptr_t", ffi.addressof(lib, "cpSpaceStep")))


def layout_matches(ffi, lib) -> bool:
    """True if a pymunk body's memory holds position, velocity, angle and angular velocity in the
    slots this module uses (values set and read through chipmunk's own accessors)."""
    body = lib.cpBodyNew(1.0, math.inf)
    try:
        lib.cpBodySetPosition(body, (1.25, -2.5))
        lib.cpBodySetVelocity(body, (3.75, -4.5))
        lib.cpBodySetAngle(body, 0.625)
        lib.cpBodySetAngularVelocity(body, -5.25)
        slots = np.frombuffer(ffi.buffer(body, N_SLOTS * 8), dtype=np.float64)
        return bool(slots[_PX] == 1.25 and slots[_PY] == -2.5 and slots[_VX] == 3.75 and slots[_VY] == -4.5
                    and slots[_A] == 0.625 and slots[_W] == -5.25)
    finally:
        lib.cpBodyFree(body)
