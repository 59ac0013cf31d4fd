"""Named reward terms. Each agent's reward is the sum of its terms; the terms go into ``info``."""

from __future__ import annotations

import numpy as np

from parcover_env.config import RewardConfig

__all__ = ["TERMS", "REWARD_KEYS", "reward_terms"]

TERMS = ("kpoi", "progress", "time", "collision")
REWARD_KEYS = tuple(f"reward_{t}" for t in TERMS)
"""Info keys of the terms: ``info[agent]["reward_kpoi"]`` etc. (flat, present at reset as 0)."""


def reward_terms(w: RewardConfig, n_new_kpois: int, progress: np.ndarray,
                 new_contacts: np.ndarray) -> dict[str, np.ndarray]:
    """Weighted terms per agent ``{name: (N,)}``.

    kpoi: ``w.kpoi`` per KPOI newly visited by anyone (team reward, every agent);
    progress: ``w.progress`` per metre of route-length-to-go removed this step (potential-based);
    time: ``w.time`` every step; collision: ``w.collision`` per new contact of this agent.
    """
    n = len(progress)
    return {
        "kpoi": np.full(n, w.kpoi * n_new_kpois),
        "progress": w.progress * progress,
        "time": np.full(n, w.time),
        "collision": w.collision * new_contacts.astype(float),
    }
