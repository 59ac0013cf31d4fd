"""The observation spec is the one declaration: layout, bounds, docstring table and kernel columns."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.envs import ParallelCoverageEnv
from parcover_env.envs.obs_spec import ENTRIES, KERNEL_COLUMNS, KERNEL_ENTRIES, markdown_table
from parcover_env.envs.observations import ScalarInputs


def _doc_rows() -> list[list[str]]:
    doc = ParallelCoverageEnv.__doc__
    lines = [ln.strip() for ln in doc.splitlines() if ln.strip().startswith("|")]
    table = lines[:lines.index("|---|---|---|---|---|---|---|---|") + 1 + len(ENTRIES)]  # the first table
    return [[c.strip() for c in ln.strip("|").split("|")] for ln in table[2:]]


def test_the_docstring_table_is_the_generated_one():
    rows = _doc_rows()
    assert [r[0] for r in rows] == [e.name for e in ENTRIES]
    assert [r[2] for r in rows] == [e.unit for e in ENTRIES]
    assert [r[4] for r in rows] == [e.source for e in ENTRIES]
    assert [r[6] for r in rows] == [", ".join(f"v{v}" for v in e.versions) for e in ENTRIES]
    assert [r[7] for r in rows] == [e.meaning for e in ENTRIES]
    assert markdown_table().replace("\n", "\n    ") in ParallelCoverageEnv.__doc__
    assert "OBSERVATION_TABLE" not in ParallelCoverageEnv.__doc__


@pytest.mark.parametrize("preset", ["realistic", "ideal"])
def test_layout_and_space_follow_the_spec_order_and_bounds(preset):
    env = parcover_env.parallel_env("office", preset=preset)
    s, box = env.scenario, env.map.bounds
    names = [e.name for e in ENTRIES if e.n_columns(s, env.sensors.get(e.name))]
    assert list(env.layout.names) == names
    assert all(preset in e.presets for e in ENTRIES if e.name in names)  # the table's presets column holds
    space = env.observation_space(env.possible_agents[0])
    for e in ENTRIES:
        if e.name in names:
            lo, hi = e.bounds(s, box)
            sl = env.layout.slices[e.name]
            assert np.all(space.low[sl] == np.float32(lo)) and np.all(space.high[sl] == np.float32(hi))
    assert env.layout.slices["sonar"].stop - env.layout.slices["sonar"].start == env.sonar.n_beams


def test_kernel_columns_are_the_non_sensor_entries_and_all_are_written():
    assert KERNEL_COLUMNS.names == KERNEL_ENTRIES
    assert set(KERNEL_ENTRIES) == {e.name for e in ENTRIES if e.source not in ("sensor", "route", "teammates", "scan")}
    assert {e.name for e in ENTRIES if e.source == "scan"} == {"scanning", "scan_result"}  # the stepper's
    env = parcover_env.parallel_env("office")
    lay, n = env.layout, 3
    g = np.random.default_rng(1)
    cov = np.broadcast_to(np.diag([0.04, 0.01, 0.001]), (n, 3, 3)).copy()
    inputs = ScalarInputs(g.uniform(1, 3, (n, 3)), g.uniform(-0.1, 0.1, (n, 2)), np.array([True, False, False]),
                          np.arange(n), np.full(n, 2.0), cov, g.uniform(1, 3, (n, 2)), g.uniform(-1, 1, (n, 2)),
                          g.uniform(-1, 1, n), np.array([False, True, True]), 0.5, 0.25)
    obs = np.full((n, lay.size), np.nan, np.float32)
    lay.fill_scalars(obs, inputs)
    for name in KERNEL_ENTRIES:
        assert np.isfinite(obs[:, lay.slices[name]]).all(), name
    assert np.isnan(obs[:, lay.slices["sonar"]]).all()  # sensor columns are the stepper's
    assert lay.columns[0]["sigma_major"] == lay.slices["sigma_major"].start
    np.testing.assert_array_equal(obs[:, lay.slices["sigma_major"]].ravel(), np.float32(0.2))
    np.testing.assert_array_equal(obs[:, lay.slices["slot"]].ravel(), np.float32([0.0, 0.5, 1.0]))


def test_an_absent_entry_has_column_minus_one():
    env = parcover_env.parallel_env("office", preset="ideal")
    assert env.layout.columns[0]["sigma_major"] == -1 and "sigma_major" not in env.layout.slices
