"""The one angle wrap: the Python scalar, its compiled form for kernels and its ufunc over arrays
are one formula, ``pi - ((pi - a) mod 2 pi)``, with the same bits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from parcover_env.geometry.angle_kernels import wrap as compiled_wrap
from parcover_env.geometry.angles import atan2, wrap, wrap_angle


@njit
def _wrap_all(a, out):
    for i in range(a.shape[0]):
        out[i] = compiled_wrap(a[i])


@pytest.mark.parametrize(("a", "want"), [
    (0.0, 0.0), (math.pi, math.pi), (-math.pi, math.pi), (1.5 * math.pi, -0.5 * math.pi),
    (-1.5 * math.pi, 0.5 * math.pi), (2 * math.pi + 0.25, 0.25), (-7 * math.pi - 0.5, math.pi - 0.5),
])
def test_wrap_maps_into_the_half_open_interval(a, want):
    """(-pi, pi]: -pi maps to +pi, whole turns vanish, the rest keeps its sign."""
    assert wrap(a) == pytest.approx(want, abs=1e-12)
    assert float(wrap_angle(a)) == pytest.approx(want, abs=1e-12)
    assert -math.pi < wrap(a) <= math.pi


def test_the_three_forms_have_the_same_bits():
    """Scalar Python, compiled scalar and ufunc agree bit for bit with numpy's ``pi - mod(pi - a, 2 pi)``
    on ordinary angles, whole turns and their neighbours, large angles and signed zeros."""
    rng = np.random.default_rng(3)
    turns = np.arange(-6, 7) * np.pi
    a = np.concatenate([rng.normal(0, s, 3000) for s in (1e-9, 1.0, 4.0, 1e4, 1e9)]
                       + [turns, np.nextafter(turns, np.inf), np.nextafter(turns, -np.inf), [0.0, -0.0]])
    want = np.pi - np.mod(np.pi - a, 2.0 * np.pi)
    compiled = np.empty_like(a)
    _wrap_all(a, compiled)
    assert wrap_angle(a).tobytes() == want.tobytes()
    assert compiled.tobytes() == want.tobytes()
    assert np.array([wrap(x) for x in a.tolist()]).tobytes() == want.tobytes()


def test_wrap_angle_keeps_shapes_and_scalars():
    assert wrap_angle(np.zeros((2, 3)) + 4.0).shape == (2, 3)
    assert isinstance(wrap_angle(4.0), np.floating) and wrap_angle(4.0) == pytest.approx(4.0 - 2 * math.pi)
    assert wrap_angle([7, -7]).tolist() == pytest.approx([7 - 2 * math.pi, 2 * math.pi - 7])


def test_atan2_arrays_equal_libm_scalars():
    y, x = np.array([1.0, -2.0, 0.5]), np.array([-3.0, 0.1, 0.0])
    assert atan2(y, x).tolist() == [math.atan2(a, b) for a, b in zip(y.tolist(), x.tolist(), strict=True)]
    assert atan2(1.0, -1.0) == math.atan2(1.0, -1.0)
