"""docs/evaluation.md: the sets it names are disjoint, the trainer refuses the test maps, and the results
page marks the rows measured on the retired maps 1000-1019 as validation-grade."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from parcover_env.errors import ConfigError
from parcover_env.harness.map_pool import parse_pool

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = (ROOT / "docs" / "evaluation.md").read_text()


def _ranges(row: str) -> list[range]:
    """The ``generated:A-B`` ranges named in the protocol table's row whose first cell is ``row``."""
    line = next(x for x in PROTOCOL.splitlines() if x.startswith(f"| {row} |"))
    cell = line.split("|")[2]
    return sorted({range(int(a), int(b) + 1) for a, b in re.findall(r"generated:(\d+)-(\d+)", cell)}, key=min)


def test_the_three_sets_are_disjoint_and_the_test_set_is_large_enough():
    (train,), (val,), (test,) = _ranges("training"), _ranges("validation"), _ranges("test")
    assert (train, val, test) == (range(0, 500), range(500, 600), range(2000, 2050))
    assert not set(train) & set(val) and not (set(train) | set(val)) & set(test)
    assert len(test) >= 50 and "--seeds 3" in PROTOCOL  # >= 50 maps x 3 episode seeds
    assert "range(2000, 2050)" in PROTOCOL and "range(500, 600)" in PROTOCOL  # the commands run those sets


def test_the_trainer_refuses_the_test_and_retired_maps_and_takes_the_training_pool():
    assert parse_pool("generated:0-499") == tuple(range(500))
    for pool in ("generated:0-2049", "generated:2000-2049", "generated:1000-1019"):
        with pytest.raises(ConfigError, match="evaluation maps"):
            parse_pool(pool)


def test_results_mark_the_retired_maps_validation_grade():
    results = (ROOT / "docs" / "results.md").read_text()
    row = next(x for x in results.splitlines() if x.startswith("| generated:* | `mappo_generated_scan_sigma` |"))
    assert "validation-grade" in row and "1000-1019" in row
    assert "Maps 1000-1019 are retired as a test set" in PROTOCOL
    assert "validation-grade" in (ROOT / "README.md").read_text()
