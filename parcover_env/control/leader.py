"""Leader control: a go-to-goal law of our choosing on the unicycle kinematics of Min et al.'s eq. 2.

Min, Fehr & Papanikolopoulos's eq. 2 gives only the leader's discrete unicycle kinematics
(x += v cos(theta) dt, y += v sin(theta) dt, theta += omega dt) and says the control velocities are
found "using the position information"; it gives no control law. :func:`go_to_goal` is ours: a
saturated polar go-to-goal law toward the next waypoint (``tests/control/test_leader.py``).
"""

from __future__ import annotations

import numpy as np

from parcover_env.geometry import atan2

__all__ = ["go_to_goal"]


def go_to_goal(goal_xy: np.ndarray, max_speed: float, max_turn_rate: float, k_rho: float = 1.0,
               k_alpha: float = 2.0, speed_scale: float = 1.0) -> tuple[float, float]:
    """``(v, omega)`` driving a unicycle to ``goal_xy`` given in its own frame (x ahead, y left).

    rho = |goal|, alpha = bearing; v = min(speed_scale * v_max, k_rho * rho) * max(cos alpha, 0)^2
    (turn in place toward goals behind), omega = k_alpha * alpha; both saturated.
    """
    rho = float(np.hypot(goal_xy[0], goal_xy[1]))
    alpha = float(atan2(goal_xy[1], goal_xy[0]))
    v = min(speed_scale * max_speed, k_rho * rho) * max(np.cos(alpha), 0.0) ** 2
    w = float(np.clip(k_alpha * alpha, -max_turn_rate, max_turn_rate))
    return float(np.clip(v, -max_speed, max_speed)), w
