"""The scan phase of :class:`~parcover_env.expert.navigator.SonarNavigator` (Kim, Pearce & Amato Fig. 1
line 8): the robots scan one by one, standing still, and each scan is booked as a fix or a miss.

With the env's sonar localization service (``observation.scan``, the navigator's
:attr:`~parcover_env.expert.navigator.SonarNavigator.env_scan`) a robot asks with the ``scan``
action component, is held still while its ``scanning`` entry is 1, and then reads ``scan_result``;
the env's fix is already in its estimate (the observed pose) and covariance. Without the service the
navigator turns the robot in place, bins its sonar readings into a 360-degree scan and localizes it
itself (:class:`~parcover_env.expert.team_localizer.TeamLocalizer`).
"""

from __future__ import annotations

import numpy as np

from parcover_env.geometry.poses import compose as _compose
from parcover_env.geometry.poses import inverse as _inverse
from parcover_env.localization.sonar.scan import ScanCollector

__all__ = ["NavigatorScans"]


class NavigatorScans:
    """Scan-phase methods of the navigator (a mixin: they use the navigator's state)."""

    def _scan_step(self, observations, cmd: np.ndarray) -> None:
        while self.queue and f"robot_{self.queue[0]}" not in observations:
            self.queue.pop(0)
        if not self.queue:
            self._end_iteration()
            return
        i = self.queue[0]
        odom = self.last_odom[i]
        if self.env_scan:
            self._env_scan_step(i, observations[f"robot_{i}"], cmd)
            return
        if self.scan is None:
            if abs(float(self.layout.get(observations[f"robot_{i}"], "v")[0])) > self.p.stop_speed:
                cmd[i] = 0.0  # still rolling: a scan is taken standing still
                return
            self.scan = {"robot": i, "start": odom.copy(),
                         "col": ScanCollector(self.beams, self.n_bins, self.sonar_cfg.range_max, float(odom[2]),
                                              self.p.bin_tol_deg)}
            self._stats["scans"] += 1
        ranges = self.layout.get(observations[f"robot_{i}"], "sonar").astype(float)
        full = self.scan["col"].add(float(odom[2]), ranges)
        if full:
            self._finish_scan(i)
            self.queue.pop(0)
            self.scan = None
            if not self.queue:
                self._end_iteration()
            return
        self._stats["scan_steps"] += 1
        cmd[i] = [0.0, self.p.scan_rate]

    def _env_scan_step(self, i: int, obs: np.ndarray, cmd: np.ndarray) -> None:
        """Robot ``i``'s scan by the env's service: stop, ask (``scan`` component), hold still while
        the ``scanning`` entry is 1, then read the outcome (``scan_result``)."""
        g = self.layout.get
        cmd[i] = 0.0
        if self.scan is None:
            if abs(float(g(obs, "v")[0])) > self.p.stop_speed:
                return  # still rolling: a scan is taken standing still
            self.scan = {"robot": i, "start": self.last_odom[i].copy()}
            self.request[i] = True
            self._stats["scans"] += 1
            return
        if g(obs, "scanning")[0] > 0.5:
            self._stats["scan_steps"] += 1
            return
        self._finish(i, self.scan["start"], bool(g(obs, "scan_result")[0] > 0.5), None)
        self.queue.pop(0)
        self.scan = None
        if not self.queue:
            self._end_iteration()

    def _finish(self, i: int, prior: np.ndarray, ok: bool, fix: np.ndarray | None) -> None:
        """Book a scan of robot ``i`` from belief ``prior``: accepted (``ok``) or not; ``fix`` the
        localized pose of the navigator's own scan (None: the env's fix, already in its estimate)."""
        at_end = self.targets[i] >= self.paths[i].s[-1] - 1e-9
        if at_end:
            self.final_scans[i] += 1
        if ok:
            self._stats["localized"] += 1
            pose = self.last_odom[i] if fix is None else fix
            self._stats["corrections"].append(float(np.hypot(*(pose[:2] - prior[:2]))))
            if fix is not None:
                self.correction[i] = _compose(fix, _inverse(self.scan["start"]))
            if fix is not None or not self.env_cov:  # else the next observation carries the env's
                self.cov[i] = self.fix_cov
            self.travelled[i] = self.turned[i] = 0.0
            self.axis0[i] = self.p.initial_axis
        else:
            self._stats["failed"] += 1
        if at_end:
            bel = _compose(self.correction[i], self.last_odom[i])
            close = np.hypot(*(bel[:2] - self.paths[i].xy[-1])) <= self.p.goal_tol
            if (ok and close) or self.final_scans[i] >= self.p.max_final_scans:
                self.done[i] = True

    def _finish_scan(self, i: int) -> None:
        ranges = self.scan["col"].ranges  # bins never reached keep the max range (no echo)
        o = self.scan["start"]
        prior = _compose(self.correction[i], o)
        ell = self.region(i, prior[:2])
        sigma = np.delete([max(self.ellipse(j).axes) for j in range(self.n)], i)
        fix = self.team_loc.localize(ranges, ell, np.delete(self.belief()[:, :2], i, axis=0), heading=prior[2],
                                     others_sigma=sigma)
        res, ok, team_error = fix.result, fix.ok, fix.team_error
        record = {"robot": i, "prior": prior, "ellipse": ell, "success": bool(ok), "error": res.error,
                  "pose": None if res.pose is None else res.pose.copy(), "target": self.targets[i],
                  "team_error": team_error}
        self.fixes.append(record)
        self._finish(i, prior, bool(ok), res.pose if ok else None)
