"""The compiled assembly of the observation's scalar entries against the numpy formulas."""

from __future__ import annotations

import numpy as np
import pytest
from layout_helpers import layout_of

from parcover_env.envs.observations import MAX_FIX_AGE, SCALAR_ENTRIES, ScalarInputs, ellipse_entries
from parcover_env.geometry import rotate


def _numpy_rows(layout, est, vel, leader, slot, fix_age, cov, goals, rel_xy, rel_heading, visible, kpois, time):
    L, n = layout.slices, len(est)
    obs = np.zeros((n, layout.size), dtype=np.float32)
    obs[:, L["x"]], obs[:, L["y"]] = est[:, 0:1], est[:, 1:2]
    obs[:, L["cos_theta"]], obs[:, L["sin_theta"]] = np.cos(est[:, 2:3]), np.sin(est[:, 2:3])
    obs[:, L["v"]], obs[:, L["omega"]] = vel[:, 0:1], vel[:, 1:2]
    obs[:, L["leader"]] = leader[:, None]
    obs[:, L["slot"]] = slot[:, None] / max(n - 1, 1)
    obs[:, L["fix_age"]] = np.minimum(fix_age, MAX_FIX_AGE)[:, None]
    if "sigma_major" in L:
        obs[:, L["sigma_major"].start:L["sigma_heading"].stop] = ellipse_entries(cov, est[:, 2])
    goal = rotate(goals - est[:, :2], -est[:, 2])
    obs[:, L["goal_dx"]], obs[:, L["goal_dy"]] = goal[:, 0:1], goal[:, 1:2]
    obs[:, L["pred_dx"]], obs[:, L["pred_dy"]] = rel_xy[:, 0:1], rel_xy[:, 1:2]
    obs[:, L["pred_cos"]] = np.where(visible, np.cos(rel_heading), 0.0)[:, None]
    obs[:, L["pred_sin"]] = np.where(visible, np.sin(rel_heading), 0.0)[:, None]
    obs[:, L["pred_visible"]] = visible[:, None]
    obs[:, L["kpois_visited"]] = kpois
    obs[:, L["time"]] = time
    return obs


@pytest.mark.parametrize("covariance, n", [(True, 9), (False, 9), (True, 2)])
def test_compiled_scalar_entries_equal_the_numpy_formulas(covariance, n):
    layout = layout_of((0, 0, 10, 8), 0.5, 1.5, 16, 3.0, 2.5, covariance=covariance)
    g = np.random.default_rng(0)
    est = np.column_stack([g.uniform(0, 10, (n, 2)), g.uniform(-4, 4, n)])
    m = g.normal(size=(n, 3, 3)) * 0.1
    cov = m @ m.transpose(0, 2, 1)
    cov[0] = np.diag([0.01, 0.01, 0.001])  # a circle: axis (1, 0)
    cov[1] = 0.0
    visible = g.random(n) < 0.6
    args = (est, g.uniform(-0.5, 0.5, (n, 2)), g.random(n) < 0.3, g.permutation(n), g.uniform(0, 90, n), cov,
            g.uniform(0, 10, (n, 2)), np.where(visible[:, None], g.uniform(-1, 1, (n, 2)), 0.0),
            g.uniform(-3, 3, n), visible, 0.375, 0.125)
    got = np.zeros((n, layout.size), dtype=np.float32)
    layout.fill_scalars(got, ScalarInputs(*args))
    want = _numpy_rows(layout, *args)
    assert np.array_equal(got, want)
    assert set(SCALAR_ENTRIES) - set(layout.names) == (set() if covariance else
                                                       {"sigma_major", "sigma_minor", "sigma_axis_cos2",
                                                        "sigma_axis_sin2", "sigma_heading"})
    assert not got[:, layout.slices["sonar"]].any()  # the sonar columns are left alone
    assert got[1, layout.slices["fix_age"]][0] == np.float32(min(args[4][1], MAX_FIX_AGE))
    assert sorted(got[:, layout.slices["slot"]].ravel().tolist()) == pytest.approx(np.arange(n) / (n - 1))
