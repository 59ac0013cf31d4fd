"""The geometric kernel: angles, batched ray casting, camera projection.

Conventions: points are ``(..., 2)`` float arrays in metres; a segment array is ``(S, 4)`` with
rows ``(x1, y1, x2, y2)``; angles are radians, counter-clockwise from +x, wrapped to (-pi, pi].
"""

from parcover_env.geometry.angles import atan2, rotate, wrap, wrap_angle
from parcover_env.geometry.rays import (
    RayHits,
    cast_rays,
    cast_rays_discs,
    point_segment_distance,
    polygon_edges,
    segments_blocked,
    sight_lines_blocked,
)

__all__ = ["wrap", "wrap_angle", "rotate", "atan2", "polygon_edges", "RayHits", "cast_rays", "cast_rays_discs",
           "segments_blocked", "sight_lines_blocked", "point_segment_distance"]
