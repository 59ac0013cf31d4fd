"""Follower l-psi control (eq. 3, corrected): converges to (l_d, psi_d) behind a moving leader."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.control.follower import LeaderVelocityEstimator, l_psi_control, relative_l_psi
from parcover_env.sensors.relative import RelativeCamera

L_D, PSI_D, D = 0.45, np.pi, 0.2


def _errors(w_leader: float, noise: bool, steps: int = 500, dt: float = 0.1):
    rng = np.random.default_rng(0)
    cam = RelativeCamera() if noise else RelativeCamera(range_noise=0.0, bearing_noise=0.0, heading_noise=0.0)
    leader, follower = np.array([1.0, 0.0, 0.0]), np.array([0.3, 0.2, 0.4])
    est, cmd, errs = LeaderVelocityEstimator(dt), (0.0, 0.0), []
    for t in range(steps):
        r = cam.measure(np.array([leader, follower]), np.array([-1, 0]), np.zeros((0, 4)), rng)
        assert r.visible[1]
        v_l, w_l = est.update(r.rel_xy[1], r.rel_heading[1], *cmd)
        cmd = l_psi_control(relative_l_psi(r.rel_xy[1], r.rel_heading[1], D), L_D, PSI_D, D, (1.0, 0.7),
                            v_l, w_l, 0.3, 1.5)
        assert -0.3 <= cmd[0] <= 0.3 and -1.5 <= cmd[1] <= 1.5
        for pose, (v, w) in ((leader, (0.24, w_leader)), (follower, cmd)):
            pose += [v * np.cos(pose[2]) * dt, v * np.sin(pose[2]) * dt, w * dt]
        if t > steps // 2:
            q = follower[:2] + D * np.array([np.cos(follower[2]), np.sin(follower[2])])
            d = q - leader[:2]
            psi = np.arctan2(d[1], d[0]) - leader[2]
            errs.append((np.hypot(*d) - L_D, np.angle(np.exp(1j * (psi - PSI_D)))))
    return np.sqrt(np.mean(np.square(errs), axis=0))


@pytest.mark.parametrize("w_leader", [0.0, 0.3], ids=["straight", "curve"])
def test_converges_behind_leader_exact_measurements(w_leader):
    e_l, e_psi = _errors(w_leader, noise=False)
    assert e_l < 0.005 and e_psi < 0.01


@pytest.mark.parametrize("w_leader", [0.0, 0.3], ids=["straight", "curve"])
def test_converges_with_camera_noise(w_leader):
    e_l, e_psi = _errors(w_leader, noise=True)
    assert e_l < 0.02 and e_psi < 0.05


def test_relative_geometry_directly_behind():
    m = relative_l_psi(np.array([0.65, 0.0]), 0.0, D)  # leader 0.65 m ahead, same heading
    assert m.l == pytest.approx(0.45) and abs(abs(m.psi) - np.pi) < 1e-9 and abs(abs(m.gamma) - np.pi) < 1e-9
