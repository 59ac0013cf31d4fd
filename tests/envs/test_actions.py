"""Joint-action validation: clip out-of-range, reject malformed, never a partial update."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.errors import ActionError
from parcover_env.sim.act_phase import to_commands

AGENTS = ["robot_0", "robot_1"]


def test_scaling_and_clipping():
    cmd = to_commands({"robot_0": [0.5, -1.0], "robot_1": [3.0, -7.0]}, AGENTS, 0.2, 1.5)
    np.testing.assert_allclose(cmd, [[0.1, -1.5], [0.2, -1.5]])


@pytest.mark.parametrize("actions,words", [
    ({"robot_0": [np.nan, 0.0], "robot_1": [0, 0]}, "robot_0: action contains NaN"),
    ({"robot_0": [0.0, np.inf], "robot_1": [0, 0]}, "NaN or inf"),
    ({"robot_0": [0.0, 0.0, 0.0], "robot_1": [0, 0]}, "shape (2,)"),
    ({"robot_0": [0.0, 0.0]}, "missing actions for agents ['robot_1']"),
    ({"robot_0": [0, 0], "robot_1": [0, 0], "robot_7": [0, 0]}, "unknown or finished agents ['robot_7']"),
    ({"robot_0": "fast", "robot_1": [0, 0]}, "not numeric"),
    ([[0, 0], [0, 0]], "must be a dict"),
])
def test_bad_actions_raise_one_clear_error(actions, words):
    with pytest.raises(ActionError) as info:
        to_commands(actions, AGENTS, 0.2, 1.5)
    assert words in str(info.value)
