"""The package's one angle-wrap formula, plain Python, with no imports of the package: the floor
under :mod:`parcover_env.geometry.angles` (re-exported there as ``wrap``) and
:mod:`parcover_env.geometry.angle_kernels` (compiled there for kernels and as a ufunc)."""

from __future__ import annotations

import math

__all__ = ["wrap"]


def wrap(a: float) -> float:
    """One angle ``a`` (rad) wrapped to (-pi, pi]: ``pi - ((pi - a) mod 2 pi)``, the mod taking the
    sign of ``2 pi``. Compiled code uses it through :func:`parcover_env.geometry.angle_kernels.wrap`
    and arrays through :func:`parcover_env.geometry.angles.wrap_angle`."""
    return math.pi - ((math.pi - a) % (2.0 * math.pi))
