"""Follower control (Min et al. eq. 3, implemented as Das et al.'s l-psi law) from onboard measurements.

Geometry (ALGORITHMS.md): the follower's control point q = p_F + d (cos th_F, sin th_F);
l = |q - p_L|; psi = atan2(q - p_L) - th_L (psi = pi: directly behind); gamma = th_L + psi - th_F.
Feedback linearization with gains a1, a2 gives
    A = a1 (l_d - l) + v_L cos psi,   B = a2 l wrap(psi_d - psi) - v_L sin psi + l w_L,
    v_F = A cos gamma - B sin gamma,  w_F = (A sin gamma + B cos gamma) / d,
Min et al.'s printed eq. 3 is garbled (its input matrix has a zero second column, so the angle
error would never reach the wheels). The paper says its follower law "is based upon the techniques
in [8]" and refers to [8] for details; its ref. [8] is H. J. Min, A. Drenner and N. Papanikolopoulos,
"Vision-based leader-follower formations with limited information", ICRA 2009. The paper does not
cite Das et al. The law above is the l-psi law of A. K. Das, R. Fierro, V. Kumar et al., "A
vision-based formation control framework", IEEE T-RA 18(5), 2002: our choice of a law of the same
(l, angle) form, in the coordinates above, not a law the paper prints. What we rely on is tested:
l -> l_d and psi -> psi_d from perturbed starts while the leader drives and turns
(``tests/control/test_follower.py``).

Limited information (the setting of ref. [8]'s title): the follower does not receive the leader's
velocities. It estimates them from successive camera measurements and its own motion
(:class:`LeaderVelocityEstimator`); with no history yet they are treated as a disturbance (u_L = 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from parcover_env.geometry import atan2, wrap_angle

__all__ = ["LPsi", "relative_l_psi", "l_psi_control", "LeaderVelocityEstimator"]


@dataclass(frozen=True)
class LPsi:
    l: float
    psi: float
    gamma: float


def relative_l_psi(rel_xy, rel_heading: float, offset: float) -> LPsi:
    """l, psi, gamma from the leader's position ``rel_xy`` and heading in the follower's frame."""
    qx, qy = offset - rel_xy[0], -rel_xy[1]  # q - p_L, with q = (d, 0) in the follower frame
    l = float(np.hypot(qx, qy))
    psi = float(wrap_angle(atan2(qy, qx) - rel_heading))
    return LPsi(l, psi, float(wrap_angle(rel_heading + psi)))


def l_psi_control(m: LPsi, l_d: float, psi_d: float, offset: float, gains: tuple[float, float],
                  v_leader: float, w_leader: float, max_speed: float, max_turn_rate: float,
                  min_speed: float | None = None) -> tuple[float, float]:
    """Saturated ``(v_F, w_F)`` of the l-psi law."""
    a1, a2 = gains
    A = a1 * (l_d - m.l) + v_leader * np.cos(m.psi)
    B = a2 * m.l * float(wrap_angle(psi_d - m.psi)) - v_leader * np.sin(m.psi) + m.l * w_leader
    v = A * np.cos(m.gamma) - B * np.sin(m.gamma)
    w = (A * np.sin(m.gamma) + B * np.cos(m.gamma)) / offset
    lo = -max_speed if min_speed is None else min_speed
    return float(np.clip(v, lo, max_speed)), float(np.clip(w, -max_turn_rate, max_turn_rate))


class LeaderVelocityEstimator:
    """Leader (v, w) from two successive relative measurements and the follower's own (v, w).

    Between t and t + dt the follower moves by its own (v_F, w_F); the leader's displacement in the
    follower's old frame is then ``(v_F dt, 0) + R(w_F dt) p_L(t + dt) - p_L(t)``. An exponential
    filter (``alpha``) smooths the camera noise.
    """

    def __init__(self, dt: float, alpha: float = 0.1):
        self.dt, self.alpha = dt, alpha
        self.prev: tuple[np.ndarray, float] | None = None
        self.v, self.w = 0.0, 0.0

    def reset(self) -> None:
        self.prev, self.v, self.w = None, 0.0, 0.0

    def update(self, rel_xy, rel_heading: float, own_v: float, own_w: float) -> tuple[float, float]:
        rel_xy = np.asarray(rel_xy, dtype=float)
        if self.prev is not None:
            p0, h0 = self.prev
            turn = own_w * self.dt
            c, s = np.cos(turn), np.sin(turn)
            p1 = np.array([own_v * self.dt + c * rel_xy[0] - s * rel_xy[1], s * rel_xy[0] + c * rel_xy[1]])
            disp = p1 - p0
            heading = h0 + 0.5 * float(wrap_angle(rel_heading + turn - h0))
            v = float(disp @ np.array([np.cos(heading), np.sin(heading)])) / self.dt
            w = float(wrap_angle(rel_heading + turn - h0)) / self.dt
            self.v += self.alpha * (v - self.v)
            self.w += self.alpha * (w - self.w)
        self.prev = (rel_xy.copy(), float(rel_heading))
        return self.v, self.w
