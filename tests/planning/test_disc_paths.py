"""DiscPaths: the free-space shortest path of a disc robot as vertices, for steering (the expert off its
route, issue 42); hand-built maps with hand-computed paths, the same lengths as free_space_distances."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from shapely.geometry import Polygon, box

from parcover_env.planning.free_space import DiscPaths, free_space_distances

L_CORRIDOR = Polygon([(0, 0), (4, 0), (4, 4), (3, 4), (3, 1), (0, 1)])
"""A 1 m wide corridor along y in [0, 1], turning left at x in [3, 4]; the inner corner is (3, 1)."""


def _length(way: np.ndarray) -> float:
    return float(np.hypot(*np.diff(way, axis=0).T).sum())


def test_in_an_empty_room_the_path_is_the_straight_line():
    paths = DiscPaths(box(0, 0, 4, 3), 0.2)
    np.testing.assert_allclose(paths.path((0.5, 0.5), (3.5, 2.5)), [[0.5, 0.5], [3.5, 2.5]])
    assert paths.clear((0.5, 0.5), (3.5, 2.5))
    # 0.1 m from the wall at x = 4: the disc's centre cannot go there, the path ends where it can
    np.testing.assert_allclose(paths.path((0.5, 0.5), (3.9, 0.5)), [[0.5, 0.5], [3.8, 0.5]], atol=1e-12)
    assert not paths.clear((0.5, 0.5), (3.9, 0.5))


def test_the_l_corridor_path_rounds_the_inflated_corner_at_the_radius():
    r = 0.2
    paths = DiscPaths(L_CORRIDOR, r)
    way = paths.path((0.5, 0.5), (3.5, 3.5))
    np.testing.assert_allclose(way[0], [0.5, 0.5])
    np.testing.assert_allclose(way[-1], [3.5, 3.5])
    bends = way[1:-1]
    assert len(bends) >= 2
    # every bend lies on the corner (3, 1) inflated by r (the chords' ends are on the arc), on the corridor's side
    np.testing.assert_allclose(np.hypot(*(bends - [3.0, 1.0]).T), r, atol=1e-9)
    assert np.all(bends[:, 0] >= 3.0 - 1e-9) and np.all(bends[:, 1] <= 1.0 + 1e-9)
    # the same length as the distance function (the same taut string)
    want = free_space_distances(L_CORRIDOR, (0.5, 0.5), [(3.5, 3.5)], radius=r)[0]
    assert _length(way) == pytest.approx(want, abs=1e-9)
    assert _length(way) == pytest.approx(2 * 2.54165 + 0.2 * 1.3331, abs=3e-4)  # by hand (test_free_space)
    # the straight line cuts the corner: not clear for the disc, though a point could almost pass
    assert not paths.clear((0.5, 0.5), (3.5, 3.5))


def test_a_start_closer_to_a_wall_than_the_radius_backs_out_first():
    """A robot touching a door jamb (0.12 m from it, the clearance 0.17 m): the path starts at the nearest
    point where the disc fits, straight away from the jamb."""
    two_rooms = box(0, 0, 2, 2).union(box(2, 0.5, 2.1, 1.5)).union(box(2.1, 0, 4, 2))  # a 1 m door at x = 2-2.1
    paths = DiscPaths(two_rooms, 0.17)
    way = paths.path((2.05, 1.38), (0.5, 1.9))  # in the door gap, 0.12 m below its upper jamb (y = 1.5)
    np.testing.assert_allclose(way[0], [2.05, 1.33], atol=1e-9)  # 0.17 m below it
    np.testing.assert_allclose(np.hypot(*(way[1] - [2.0, 1.5])), 0.17, atol=1e-9)  # then round the jamb's corner


def test_rooms_joined_by_a_door_narrower_than_the_disc_have_no_path():
    two_rooms = box(0, 0, 2, 2).union(box(2, 0.95, 2.1, 1.25)).union(box(2.1, 0, 4, 2))  # a 0.3 m door
    assert DiscPaths(two_rooms, 0.16).path((1.0, 1.0), (3.1, 1.0)) is None
    way = DiscPaths(two_rooms, 0.1).path((1.0, 1.0), (3.1, 1.0))
    assert way is not None and _length(way) == pytest.approx(2.1025, abs=2e-3)  # by hand in test_free_space


def test_it_pickles_and_rejects_a_negative_radius():
    paths = DiscPaths(L_CORRIDOR, 0.2)
    again = pickle.loads(pickle.dumps(paths))
    np.testing.assert_array_equal(again.path((0.5, 0.5), (3.5, 3.5)), paths.path((0.5, 0.5), (3.5, 3.5)))
    with pytest.raises(ValueError, match="radius"):
        DiscPaths(L_CORRIDOR, -0.1)
    assert math.isfinite(_length(paths.path((0.5, 0.5), (0.5, 0.6))))
