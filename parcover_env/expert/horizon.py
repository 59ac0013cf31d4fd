"""How far a robot may drive before it must stop and scan: Kim, Pearce & Amato §3.1's original rule.

"The original algorithm simply selects the subgoal closest to the goal whose uncertainty ellipse is
not in collision ... if the uncertainty ellipse grows large enough that it intersects an obstacle,
then the path node right before the collision is chosen." The uncertainty region predicted at each
node ahead is the one the navigator will search when it scans there
(:meth:`~parcover_env.expert.navigator.SonarNavigator.region`): the ``region_sigmas`` ellipse of the
belief's covariance propagated along the path with the robot's odometry model, widened by the seed
B ellipse grown by the distance and rotation to that node. It is in collision when it leaves the
known free space shrunk by the robot's radius (where the robot's centre can be). Only collisions
caused by growth count: a node where even the region right after a fix would not fit (close to a
wall at the route's start or end) does not end the horizon.
"""

from __future__ import annotations

import numpy as np
import shapely

from parcover_env.config import OdometryConfig
from parcover_env.expert.config import NavigatorConfig
from parcover_env.expert.sonar_fix import belief_covariance_step
from parcover_env.geometry import wrap_angle
from parcover_env.localization.sonar.localizer import Ellipse
from parcover_env.localization.sonar.subgoals import PathNodes

__all__ = ["RegionModel", "collision_horizon", "region_ellipse"]

RING = 24
"""Vertices of the polygon that stands for a region ellipse in the collision test."""


class RegionModel:
    """What predicts a robot's uncertainty region: the navigator's ellipse rates and ``region_sigmas``,
    the covariance right after a fix, the robot's odometry model and where its centre can be."""

    def __init__(self, params: NavigatorConfig, fix_cov: np.ndarray, odometry: OdometryConfig, wheel_base: float,
                 map_model, radius: float):
        self.p, self.fix_cov = params, np.asarray(fix_cov, dtype=float)
        self.odometry, self.wheel_base = odometry, wheel_base
        self.c_free = map_model.free.buffer(-radius)
        shapely.prepare(self.c_free)


def region_ellipse(center, cov: np.ndarray, grown: float, n_sigma: float) -> Ellipse:
    """The ``n_sigma`` ellipse of the position covariance ``cov (3, 3)`` widened in every direction by
    ``grown`` (m; the Kim, Pearce & Amato ellipse's semi-axis)."""
    return Ellipse.from_covariance(center, np.asarray(cov)[:2, :2] + (grown / n_sigma) ** 2 * np.eye(2), n_sigma)


def collision_horizon(path: PathNodes, start: float, stop: float, cov: np.ndarray, travelled: float,
                      turned: float, axis0: float, model: RegionModel) -> float:
    """Label of the last node of ``path`` in ``[start, stop]`` before the predicted region (from the
    belief's covariance ``cov (3, 3)``, ``travelled`` m and ``turned`` rad since the last fix, Kim, Pearce & Amato
    axis ``axis0``) first collides by growth; ``stop`` if it never does. See the module docstring."""
    k = np.nonzero((path.s >= start - 1e-9) & (path.s <= stop + 1e-9))[0]
    if len(k) < 2:
        return stop
    xy = path.xy[k]
    d = np.diff(xy, axis=0)
    heading = np.arctan2(d[:, 1], d[:, 0])
    heading = np.append(heading, heading[-1])
    poses = np.column_stack([xy, heading])
    p, n_sigma = model.p, model.p.region_sigmas
    dist = travelled + np.concatenate([[0.0], np.cumsum(np.hypot(*d.T))])
    rot = turned + np.concatenate([[0.0], np.cumsum(np.abs(wrap_angle(np.diff(heading))))])
    grown = axis0 + p.rate_distance * dist + p.rate_rotation * rot
    fresh = region_ellipse((0.0, 0.0), model.fix_cov, p.initial_axis, n_sigma)
    regions, fits_fresh, c = [], [], np.asarray(cov, dtype=float)
    for a in range(len(k)):
        if a:
            c = belief_covariance_step(c, poses[a - 1], poses[a], heading[a - 1], model.odometry, model.wheel_base)
        regions.append(region_ellipse(xy[a], c, float(grown[a]), n_sigma).polygon(RING))
        fits_fresh.append(fresh.moved(xy[a]).polygon(RING))
    inside = shapely.contains(model.c_free, regions)
    collides = ~inside & shapely.contains(model.c_free, fits_fresh)
    first = int(np.argmax(collides)) if collides.any() else len(k)
    return float(path.s[k[max(first - 1, 0)]]) if first < len(k) else stop

