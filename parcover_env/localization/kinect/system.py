"""The overhead Kinect system in the env: sensors, marker localization, identity tracking.

Every Kinect produces a frame when the simulated clock passes its next tick (``rate_hz``; at most
one frame per control step). Leaders carry the markers (Min et al.: only leaders are localized); the
tracker matches the detections to the leaders' predicted poses (their current estimates) and the
matched leaders receive a pose fix. ``kinect: estimate`` samples the pipeline's calibrated error
model (fast); ``kinect: frames`` renders depth + IR frames and runs the full pipeline, for the
Kinects whose view can hold a leader (``KinectSensor.may_see``): a Kinect with no leader near its
view renders nothing at that tick, which changes no detection since only markers are detected.

Hand-over (Alg. 1, "change the robot located at P to the leader"): a follower promoted at a split
has driven on odometry alone and its estimate may be tens of centimetres off, along the column,
where the next robots stand; matched by that estimate, two promoted robots can swap identities and
then each receive the other's fixes for the rest of the episode. The system therefore locates a
promoted robot where the formation puts it: the pose of the robot ahead composed with the
follower camera's last measurement of it (:func:`handover_poses`, chained down the column), and
matches it by that pose until its first detection.
"""

from __future__ import annotations

import numpy as np
import shapely

from parcover_env.config import Scenario
from parcover_env.geometry.poses import compose, inverse
from parcover_env.localization.kinect.batch_update import update_systems
from parcover_env.localization.kinect.estimate_model import FastModel
from parcover_env.localization.kinect.pipeline import PipelineParams, PoseEstimate, estimate_poses
from parcover_env.localization.kinect.tracker import KinectTracker
from parcover_env.sensors.kinect import KinectFrame, KinectSensor, may_see_all
from parcover_env.world.map_model import MapModel

__all__ = ["KinectSystem", "handover_poses"]


def handover_poses(promoted: np.ndarray, predecessor: np.ndarray, rel_xy: np.ndarray, rel_heading: np.ndarray,
                   visible: np.ndarray, reference: np.ndarray) -> dict[int, np.ndarray]:
    """Where the formation puts the ``promoted`` robots ``(N,)`` bool: robot ``i`` at the pose of its
    ``predecessor[i]`` composed with the inverse of its camera measurement of it (``rel_xy[i]``, m, in
    ``i``'s frame; ``rel_heading[i]``, rad), if it saw it (``visible[i]``). The predecessor's pose is
    its own hand-over pose when it is promoted too (robots are handled in index order, the column's
    order), else ``reference[p]`` (``(N, 3)``: the poses the system holds, e.g. Kinect-fixed
    estimates). Returns ``{robot: (x, y, theta)}`` for the promoted robots that saw the robot ahead."""
    out: dict[int, np.ndarray] = {}
    for i in np.flatnonzero(promoted):
        p = int(predecessor[i])
        if p < 0 or not visible[i]:
            continue
        ahead = out.get(p, reference[p])
        rel = np.array([rel_xy[i, 0], rel_xy[i, 1], rel_heading[i]], dtype=float)
        out[int(i)] = compose(ahead, inverse(rel))
    return out


class KinectSystem:
    def __init__(self, scenario: Scenario, world_map: MapModel):
        r = scenario.robot
        self.mode = scenario.observation.kinect
        self.sensors = [KinectSensor(k, r.radius, r.height, world_map, wall_height=k.wall_height,
                                     marker_radius=r.marker_radius) for k in scenario.kinects]
        self.params = PipelineParams(marker_height=r.height, robot_radius=r.radius, marker_radius=r.marker_radius)
        self.periods = np.array([1.0 / k.rate_hz for k in scenario.kinects])
        self.tracking = scenario.kinect_tracking
        self.footprint = shapely.union_all([s.camera.footprint(r.height) for s in self.sensors])
        """Where any Kinect sees a robot's markers (union of the footprints at the robots' height)."""
        shapely.prepare(self.footprint)
        self.last_fixes: dict[int, np.ndarray] = {}
        """Pose fixes of the last :meth:`update` (Alg. 1 splits on these detections)."""
        self.reset()

    def in_view(self, xy: np.ndarray) -> np.ndarray:
        """Per point ``(N, 2)``: inside some Kinect's footprint."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        return shapely.contains_xy(self.footprint, xy[:, 0], xy[:, 1])

    def reset(self, rng: np.random.Generator | None = None) -> None:
        """New episode: fresh tracker; with ``rng``, every Kinect draws its mounting error."""
        if rng is not None:
            for sensor in self.sensors:
                sensor.mount(rng)
        self.fast = FastModel(self.sensors) if self.mode != "frames" and self.sensors else None
        """The estimate model of the Kinects as mounted (rebuilt at every remount)."""
        t = self.tracking
        self.tracker = KinectTracker(gate=t.gate, fuse_radius=t.fuse_radius)
        self.next_tick = np.zeros(len(self.sensors))
        self.frames: dict[str, KinectFrame] = {}
        self.last_fixes = {}
        self.handover: dict[int, np.ndarray] = {}
        """Promoted robots not detected since: the correction (a pose composed on the robot's estimate)
        that puts its estimate where the formation placed it at the hand-over."""

    def hand_over(self, poses: dict[int, np.ndarray], estimates: np.ndarray) -> None:
        """Promoted robots located by the formation (:func:`handover_poses`) when their estimates were
        ``estimates`` ``(N, 3)``: matched by those poses (moved on with their odometry) until detected."""
        for i, pose in poses.items():
            self.handover[int(i)] = compose(np.asarray(pose, dtype=float), inverse(estimates[i]))

    def update(self, time: float, true_poses: np.ndarray, markers: np.ndarray, predicted: np.ndarray,
               rng: np.random.Generator) -> dict[int, np.ndarray]:
        """Pose fixes ``{robot index: (x, y, theta)}`` for the marker carriers seen at this step:
        :func:`~parcover_env.localization.kinect.batch_update.update_systems` of this system alone."""
        return update_systems([self], [time], np.asarray(true_poses, dtype=float)[None],
                              np.asarray(markers, dtype=bool)[None],
                              np.asarray(predicted, dtype=float)[None], [rng])[0]

    def frame_estimates(self, due: np.ndarray, true_poses: np.ndarray, markers: np.ndarray,
                        rng: np.random.Generator, time: float) -> list[list[PoseEstimate]]:
        """``kinect: frames``: the estimates of the Kinects ``due`` (indices into ``sensors``) whose
        view can hold a marker, each rendering a frame (kept in :attr:`frames`) for the full pipeline."""
        due_sensors = [self.sensors[k] for k in due]
        per_kinect = []
        for sensor, seeing in zip(due_sensors, may_see_all(due_sensors, true_poses, markers).tolist(), strict=True):
            if not seeing:  # no marker can be in this image: no frame
                self.frames.pop(sensor.name, None)
                continue
            frame = sensor.measure(true_poses, markers, rng, stamp=time)
            self.frames[sensor.name] = frame
            per_kinect.append(estimate_poses(frame, sensor.camera, self.params))
        return per_kinect

    def track(self, per_kinect: list[list[PoseEstimate]], markers: np.ndarray, predicted: np.ndarray,
              time: float) -> dict[int, np.ndarray]:
        """Match the estimates of this step's Kinects to the marker carriers (``markers (N,)``) at
        their ``predicted (N, 3)`` poses, a promoted robot at its hand-over pose until detected;
        the matched robots' fixes (also :attr:`last_fixes`)."""
        ids = np.flatnonzero(markers)
        ref = {int(i): compose(self.handover[i], predicted[i]) if i in self.handover else predicted[i] for i in ids}
        return self.tracked(self.tracker.update(per_kinect, ref, stamp=time), markers)

    def references(self, predicted: np.ndarray) -> np.ndarray:
        """The poses ``(N, 3)`` :meth:`track` matches the marker carriers by: ``predicted`` (not copied
        when no promoted robot awaits its first detection), a promoted robot's row at its hand-over
        pose (only the carriers' rows are matched)."""
        if not self.handover:
            return predicted
        ref = np.array(predicted, dtype=float)
        for i, correction in self.handover.items():
            ref[i] = compose(correction, predicted[i])
        return ref

    def tracked(self, fixes: dict[int, np.ndarray], markers: np.ndarray) -> dict[int, np.ndarray]:
        """Take the tracker's ``fixes`` of this step (carriers ``markers (N,)``) as :attr:`last_fixes`;
        a promoted robot detected, or no longer a carrier, leaves the hand-over. Returns ``fixes``."""
        self.last_fixes = fixes
        for i in list(self.handover):
            if i in fixes or not markers[i]:
                del self.handover[i]
        return fixes

    def render_frames(self, true_poses: np.ndarray, markers: np.ndarray, seed: int) -> dict[str, KinectFrame]:
        """Frames of every Kinect now, from a separate generator (never disturbs the episode RNG)."""
        rng = np.random.default_rng(seed)
        return {s.name: s.measure(true_poses, markers, rng) for s in self.sensors}
