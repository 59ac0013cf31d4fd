"""The static wall grid: candidate walls per cell by value, and near-wall lists equal to testing
every wall (origins inside, on cell edges, outside the grid; reaches up to the grid's and beyond)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.geometry import rays
from parcover_env.geometry.wall_grid import build_wall_grid, near_segments_grid


def _lists(ox, oy, segs, reach, grid):
    idx = np.empty((len(ox), len(segs)), dtype=np.int64)
    cnt = np.empty(len(ox), dtype=np.int64)
    near_segments_grid(ox, oy, segs, reach, grid, idx, cnt)
    return [idx[o, :cnt[o]].tolist() for o in range(len(ox))]


def test_a_cell_lists_the_walls_within_reach_plus_half_its_diagonal():
    # a 4 m x 1 m box of two walls: y = 0 from x = 0 to 4 (wall 0), x = 4 from y = 0 to 1 (wall 1)
    segs = np.array([[0.0, 0.0, 4.0, 0.0], [4.0, 0.0, 4.0, 1.0]])
    grid = build_wall_grid(segs, reach=1.0, cell=1.0)
    assert grid.frame.tolist() == [0.0, 0.0, 1.0, 1.0] and grid.shape.tolist() == [4, 1]
    # cell centres (0.5, 0.5) ... (3.5, 0.5): wall 0 at 0.5 m from each; wall 1 at 3.5, 2.5, 1.5, 0.5 m;
    # a candidate within 1 + sqrt(0.5) = 1.707 m
    cells = [grid.walls[grid.start[c]:grid.start[c + 1]].tolist() for c in range(4)]
    assert cells == [[0], [0], [0, 1], [0, 1]]


@pytest.mark.parametrize("reach", [0.3, 1.0, 3.0 + rays.NEAR_SLACK, 4.5])
def test_near_lists_from_the_grid_equal_those_of_every_wall(reach):
    rng = np.random.default_rng(7)
    segs = np.ascontiguousarray(np.column_stack([rng.uniform(0, 10, (60, 2)), rng.uniform(0, 10, (60, 2))]))
    segs[5] = [3.0, 3.0, 3.0, 3.0]  # a degenerate wall
    grid = build_wall_grid(segs, 3.0 + rays.NEAR_SLACK, cell=0.5)
    lo = segs.reshape(-1, 2).min(axis=0)
    edges = lo + 0.5 * np.arange(1, 6)[:, None]  # on cell boundaries
    ox = np.concatenate([rng.uniform(-2, 12, 300), edges[:, 0], [np.nextafter(lo[0], -1), 12.0, math.nan]])
    oy = np.concatenate([rng.uniform(-2, 12, 300), edges[:, 1], [lo[1], 5.0, 1.0]])
    idx, cnt = rays.near_segments(ox, oy, segs, reach - rays.NEAR_SLACK)
    want = [idx[o, :cnt[o]].tolist() for o in range(len(ox))]
    assert _lists(ox, oy, segs, reach, grid) == want
    assert sum(map(len, want)) > 0


def test_the_grid_cuts_the_walls_tested_and_refuses_an_infinite_reach():
    rng = np.random.default_rng(8)
    segs = np.column_stack([rng.uniform(0, 20, (80, 2)), rng.uniform(0, 20, (80, 2))])
    segs[:, 2:] = segs[:, :2] + rng.uniform(-1, 1, (80, 2))  # short walls over a 20 m square
    grid = build_wall_grid(segs, 3.0)
    per_cell = np.diff(grid.start)
    assert per_cell.mean() < 0.3 * len(segs)  # each cell lists a fraction of the walls
    with pytest.raises(ValueError, match="finite reach"):
        build_wall_grid(segs, math.inf)
