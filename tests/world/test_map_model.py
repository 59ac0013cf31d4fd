"""Map geometry: free space, segments, reachability, start placement."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.config import MapConfig
from parcover_env.errors import ConfigError
from parcover_env.world.map_model import MapModel
from parcover_env.world.placement import start_poses


def test_walls_are_thickened_and_unknown_obstacles_optional():
    cfg = MapConfig(size=(4.0, 2.0), walls=(((2.0, 0.0), (2.0, 1.2)),), wall_thickness=0.2,
                    unknown_obstacles=(((0.5, 0.5), (0.9, 0.5), (0.9, 0.9), (0.5, 0.9)),))
    world, known = MapModel.from_config(cfg), MapModel.from_config(cfg, include_unknown=False)
    # square caps: the wall reaches thickness/2 past its end point (so walls meeting at corners seal)
    assert world.free.area == pytest.approx(8.0 - 0.2 * 1.3 - 0.16)
    assert known.free.area == pytest.approx(8.0 - 0.2 * 1.3)
    assert world.contains([[0.7, 0.7]]).tolist() == [False] and known.contains([[0.7, 0.7]]).tolist() == [True]
    assert not world.contains([[2.05, 0.5]])[0]
    assert world.contains([[1.0, 1.5]], margin=0.4)[0] and not world.contains([[1.0, 1.5]], margin=0.6)[0]
    assert world.segments.shape[1] == 4 and len(world.segments) >= 4 + 4 + 4


def test_reachable_region_respects_robot_radius():
    cfg = MapConfig(size=(4.0, 2.0), walls=(((2.0, 0.0), (2.0, 1.7)),), wall_thickness=0.1)
    m = MapModel.from_config(cfg)
    # the gap above the wall is 0.3 m: a 0.1 m robot passes, a 0.2 m one does not
    assert m.reachable_region((1.0, 1.0), 0.1).contains(__import__("shapely").Point(3.0, 1.0))
    assert not m.reachable_region((1.0, 1.0), 0.2).contains(__import__("shapely").Point(3.0, 1.0))


def test_start_poses_form_a_column_in_a_corridor_and_a_block_in_a_room():
    corridor = MapModel.from_config(MapConfig(size=(6.0, 0.5)))
    p = start_poses(corridor, (5.5, 0.25, 0.0), 4, 0.15, 0.5)
    np.testing.assert_allclose(p[:, 1], 0.25)
    np.testing.assert_allclose(p[:, 0], [5.5, 5.0, 4.5, 4.0])
    room = MapModel.from_config(MapConfig(size=(6.0, 6.0)))
    p = start_poses(room, (3.0, 3.0, 0.0), 9, 0.1, 0.3)
    d = np.hypot(*(p[:, None, :2] - p[None, :, :2]).transpose(2, 0, 1))
    assert d[np.triu_indices(9, 1)].min() >= 0.22
    assert np.all(p[:, 0] <= 3.0 + 1e-9)  # nobody ahead of the leader
    with pytest.raises(ConfigError, match="only 11 of 12 robots fit"):
        start_poses(corridor, (5.5, 0.25, 0.0), 12, 0.15, 0.5)


def test_segments_are_read_only_also_after_copy_and_pickle():
    """The wall segments are one read-only array (sensors key their caches on it), also in a copy
    or an unpickled map, with the same values."""
    import copy
    import pickle

    m = MapModel.from_config(MapConfig(size=(3.0, 2.0), walls=(((1.5, 0.0), (1.5, 1.2)),)))
    seg = m.segments
    assert m.segments is seg and not seg.flags.writeable and seg.flags.c_contiguous and seg.base is None
    with pytest.raises(ValueError):
        seg[0, 0] = 1.0
    for other in (copy.deepcopy(m), pickle.loads(pickle.dumps(m))):
        assert not other.segments.flags.writeable and np.array_equal(other.segments, seg)
        assert other.free.equals(m.free) and other.bounds == m.bounds
