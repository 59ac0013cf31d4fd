"""DAgger recording: the driver moves the team, the expert's actions are what gets recorded."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.harness.datasets import record_episodes


def _stack(eps, key):
    return np.concatenate([e[key] for e in eps])


def test_driver_on_every_step_moves_like_the_driver_but_records_the_expert():
    random_run = record_episodes("office", 1, seed=4, policy="random", max_steps=15)
    dagger = record_episodes("office", 1, seed=4, policy="expert", max_steps=15, driver="random", driver_prob=1.0)
    # the same states as the random team (the driver acted on every step) ...
    np.testing.assert_array_equal(_stack(dagger, "observations"), _stack(random_run, "observations"))
    # ... labelled with other actions than those executed
    assert not np.allclose(_stack(dagger, "actions"), _stack(random_run, "actions"), atol=0.05)


def test_driver_on_no_step_is_plain_expert_recording():
    expert = record_episodes("office", 1, seed=4, max_steps=15)
    dagger = record_episodes("office", 1, seed=4, max_steps=15, driver="random", driver_prob=0.0)
    np.testing.assert_array_equal(_stack(dagger, "observations"), _stack(expert, "observations"))
    np.testing.assert_array_equal(_stack(dagger, "actions"), _stack(expert, "actions"))


def test_driver_prob_outside_unit_interval_is_refused():
    with pytest.raises(ValueError, match="driver_prob"):
        record_episodes("office", 1, driver="random", driver_prob=1.5)
