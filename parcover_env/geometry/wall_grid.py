"""A static grid over a wall set that lists, per cell, the walls that can lie within a reach of a
point in the cell: built once per map (and reach), shared by every world and every step.

:func:`near_segments_grid` gives what :func:`parcover_env.geometry.ray_kernels.near_segments` gives
(the walls within ``reach`` of each origin, ascending, the same float test) while testing only the
origin's cell's candidates instead of every wall of the map. A cell's candidates are the walls
within ``reach`` plus half the cell's diagonal of its centre, with a margin, so they hold every
wall within ``reach`` of any point of the cell; an origin outside the grid tests every wall.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.ray_kernels import segment_within

__all__ = ["WallGrid", "build_wall_grid", "near_segments_grid"]

_MARGIN = 1e-6
"""Margin (m) added to a cell's candidate reach: rounding never leaves out a wall in reach."""


class WallGrid(NamedTuple):
    """Candidate walls per cell of a square grid (compressed rows, cells in row-major order)."""

    frame: np.ndarray
    """``(4,)`` float64: the grid's lower-left corner ``x0, y0`` (m), its cell size (m), the reach it
    was built for (m)."""
    shape: np.ndarray
    """``(2,)`` int64: cells along x and along y."""
    start: np.ndarray
    """``(cells + 1,)`` int64: cell ``c``'s candidates are ``walls[start[c]:start[c + 1]]``."""
    walls: np.ndarray
    """int64 wall indices, ascending within a cell."""


def build_wall_grid(segments: np.ndarray, reach: float, cell: float = 0.5) -> WallGrid:
    """The :class:`WallGrid` of ``segments (S, 4)`` for ``reach`` (m; finite), cells of ``cell`` m over
    the walls' bounding box."""
    segs = np.asarray(segments, dtype=float).reshape(-1, 4)
    if not (math.isfinite(reach) and reach >= 0 and cell > 0):
        raise ValueError(f"a wall grid needs a finite reach >= 0 and a cell > 0, got reach {reach}, cell {cell}")
    lo = segs.reshape(-1, 2).min(axis=0) if len(segs) else np.zeros(2)
    hi = segs.reshape(-1, 2).max(axis=0) if len(segs) else np.zeros(2)
    shape = np.maximum(np.ceil((hi - lo) / cell).astype(np.int64), 1)
    ix, iy = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]))  # row-major: y rows, x columns
    centres = np.column_stack([lo[0] + (ix.ravel() + 0.5) * cell, lo[1] + (iy.ravel() + 0.5) * cell])
    a, e = segs[:, :2], segs[:, 2:] - segs[:, :2]
    w = centres[:, None, :] - a[None]
    ll = np.einsum("se,se->s", e, e)
    u = np.clip(np.einsum("cse,se->cs", w, e) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
    dist = np.hypot(*(w - u[..., None] * e[None]).transpose(2, 0, 1))
    near = dist <= reach + cell * math.sqrt(0.5) + _MARGIN
    start = np.concatenate([[0], np.cumsum(near.sum(axis=1))]).astype(np.int64)
    walls = np.nonzero(near)[1].astype(np.int64)  # row-major nonzero: ascending within each cell
    return WallGrid(np.array([lo[0], lo[1], cell, reach]), shape, start, walls)


@njit(cache=True, nogil=True)
def near_segments_grid(ox, oy, segs, reach, grid, idx, cnt):
    """:func:`~parcover_env.geometry.ray_kernels.near_segments` (``idx[o, :cnt[o]]``: the segments
    within ``reach`` of origin ``o``, ascending) testing only the candidates of the origin's cell of
    the :class:`WallGrid` (built for a reach of at least ``reach``), every segment outside it."""
    x0, y0, size = grid.frame[0], grid.frame[1], grid.frame[2]
    nx, ny = grid.shape[0], grid.shape[1]
    every = grid.frame[3] < reach
    for o in range(ox.shape[0]):
        cx = math.floor((ox[o] - x0) / size)
        cy = math.floor((oy[o] - y0) / size)
        c = 0
        if every or not (0 <= cx < nx and 0 <= cy < ny):
            for s in range(segs.shape[0]):
                if segment_within(ox[o], oy[o], segs, s, reach):
                    idx[o, c] = s
                    c += 1
        else:
            cell = int(cy) * nx + int(cx)
            for q in range(grid.start[cell], grid.start[cell + 1]):
                s = grid.walls[q]
                if segment_within(ox[o], oy[o], segs, s, reach):
                    idx[o, c] = s
                    c += 1
        cnt[o] = c
