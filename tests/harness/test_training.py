"""The trainers' shared pieces live in the package: no trainer imports another; values of the helpers."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np

from parcover_env.harness import sb3_training, training

BASELINES = Path(__file__).resolve().parents[2] / "baselines"


def test_no_trainer_imports_another():
    scripts = {p.stem for p in BASELINES.glob("*.py")}
    found = []
    for path in BASELINES.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            found += [f"{path.name} imports {n}" for n in names if n.split(".")[0] in scripts]
    assert found == []


def test_discounted_returns_by_hand():
    to_go, running = sb3_training._discounted([1.0, 0.0, 2.0], 0.5)
    np.testing.assert_allclose(to_go, [1.0 + 0.5 * 1.0, 0.0 + 0.5 * 2.0, 2.0])  # g_t = r_t + gamma g_{t+1}
    np.testing.assert_allclose(running, [1.0, 0.5, 0.25 + 2.0])  # acc_t = gamma acc_{t-1} + r_t


def test_run_record_sidecar_and_csv(tmp_path):
    rec = training.RunRecord(Path("baselines/train_x.py"), ["--out", "runs/a b"], "abc123")
    rec.write_sidecar(tmp_path / "model.json", {"seed": 3})
    side = json.loads((tmp_path / "model.json").read_text())
    assert side["command"] == "python baselines/train_x.py --out 'runs/a b'" and side["git_commit"] == "abc123"
    assert side["seed"] == 3 and side["versions"]["numpy"] == np.__version__
    training.write_csv(tmp_path / "c.csv", [{"a": 1, "b": 2}, {"a": 3, "b": 4}])
    assert (tmp_path / "c.csv").read_text().splitlines() == ["a,b", "1,2", "3,4"]
    training.write_csv(tmp_path / "none.csv", [])
    assert not (tmp_path / "none.csv").exists()
