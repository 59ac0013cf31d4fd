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


def _leader_turn_rate(t: float) -> float:
    """The leader drives straight, turns left, then right (an S), then straight again."""
    return 0.0 if t < 5.0 else 0.35 if t < 15.0 else -0.35 if t < 25.0 else 0.0


@pytest.mark.parametrize("start", [(-0.2, 0.5, 0.8), (0.3, -0.6, -1.0), (-1.2, 0.0, 0.0), (0.1, 0.3, 2.5)],
                         ids=["left-ahead", "right-ahead", "far-behind", "facing-away"])
def test_eq3_converges_from_perturbed_starts_while_leader_turns(start):
    """Eq. 3 (l-psi law, exact leader velocities): l -> l_d and psi -> psi_d from perturbed starts
    while the leader drives an S; the errors shrink from the start and stay small through the turns."""
    dt, v_l = 0.05, 0.2
    leader, follower = np.array([1.0, 0.0, 0.0]), np.array(start, dtype=float)
    errs = []
    for k in range(int(35.0 / dt)):
        t = k * dt
        w_l = _leader_turn_rate(t)
        c, s = np.cos(follower[2]), np.sin(follower[2])
        rel = leader[:2] - follower[:2]
        rel_xy = np.array([c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1]])
        m = relative_l_psi(rel_xy, leader[2] - follower[2], D)
        errs.append((m.l - L_D, float(np.angle(np.exp(1j * (m.psi - PSI_D))))))
        v, w = l_psi_control(m, L_D, PSI_D, D, (1.0, 0.7), v_l, w_l, 0.5, 3.0)
        for pose, (vv, ww) in ((leader, (v_l, w_l)), (follower, (v, w))):
            pose += [vv * np.cos(pose[2]) * dt, vv * np.sin(pose[2]) * dt, ww * dt]
    errs = np.abs(np.array(errs))
    assert errs[0].max() > 0.1  # a real perturbation
    settled = errs[int(10.0 / dt):]  # from 10 s on, through both turns
    assert settled[:, 0].max() < 0.01 and settled[:, 1].max() < 0.02


def test_eq3_without_leader_feedforward_lags_in_turns():
    """The law's leader terms matter: dropping the leader's turn rate (w_L = 0 in B) leaves a
    steady psi error in a constant turn, which the full law removes."""
    dt, v_l, w_l = 0.05, 0.2, 0.35

    def final_psi_error(feedforward: bool) -> float:
        leader, follower = np.array([1.0, 0.0, 0.0]), np.array([0.35, 0.0, 0.0])
        for _ in range(int(30.0 / dt)):
            c, s = np.cos(follower[2]), np.sin(follower[2])
            rel = leader[:2] - follower[:2]
            m = relative_l_psi(np.array([c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1]]),
                               leader[2] - follower[2], D)
            v, w = l_psi_control(m, L_D, PSI_D, D, (1.0, 0.7), v_l, w_l if feedforward else 0.0, 0.5, 3.0)
            for pose, (vv, ww) in ((leader, (v_l, w_l)), (follower, (v, w))):
                pose += [vv * np.cos(pose[2]) * dt, vv * np.sin(pose[2]) * dt, ww * dt]
        return abs(float(np.angle(np.exp(1j * (m.psi - PSI_D)))))

    assert final_psi_error(True) < 0.01 < final_psi_error(False)
