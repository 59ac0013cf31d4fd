"""parcover train: bad arguments are one line and exit 2 (before any training); a tiny run end to end."""

from __future__ import annotations

import json

import pytest

from parcover_env.cli.main import main


@pytest.mark.parametrize(("argv", "words"), [
    (["train", "sac", "office", "--steps", "10", "--out", "x"], "invalid choice: 'sac'"),
    (["train", "ippo", "office", "--steps", "0", "--out", "x"], "must be >= 1"),
    (["train", "ippo", "office", "--steps", "lots", "--out", "x"], "expected an integer"),
    (["train", "ippo", "nowhere", "--steps", "10", "--out", "x"], "nowhere"),
    (["train", "ippo", "office", "--steps", "10", "--out", "x", "--ray-address", "h:1"], "needs --backend ray"),
    (["train", "ippo", "office", "--steps", "10", "--out", "x", "--config", "no.yaml"], "no.yaml: no such file"),
    (["train", "ippo", "office", "--out", "x"], "--steps"),
])
def test_bad_arguments_one_line_exit_2(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("parcover") and words in err[0]
    assert not (tmp_path / "x").exists()  # nothing written


def test_train_then_bench_the_sidecar_policy(tmp_path, capsys):
    pytest.importorskip("torchrl")
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text("frames_per_batch: 64\nminibatch_size: 32\nepochs: 1\nhidden: [8]\nepisode_steps: 40\n")
    out = tmp_path / "run"
    argv = ["train", "ippo", "office", "--steps", "100", "--out", str(out), "--seed", "2", "--config", str(cfg)]
    assert main(argv) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["command"] == "parcover " + " ".join(argv[:-2]).replace(" --seed 2", " --backend local --seed 2") \
        + f" --config {cfg}"
    assert record["agent_steps"] == 128 and record["config"]["episode_steps"] == 40
    assert f"--policies {record['policy']}" in capsys.readouterr().out
    code = main(["bench", "office", "--policies", record["policy"], "--seeds", "1", "--max-steps", "30",
                 "--workers", "1", "--out", str(tmp_path / "bench"), "--no-plots", "--quiet"])
    assert code == 0 and record["policy"] in (tmp_path / "bench" / "table.md").read_text()
