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
    (["train", "ippo", "office", "--steps", "10", "--out", "x", "--init", "nowhere"],
     "--init nowhere: no such file nowhere"),
    (["train", "ippo", "office", "--steps", "10", "--out", "x", "--config", "attention.yaml"],
     "attention.yaml: critic: attention is MAPPO's critic"),
    (["train", "mappo", "office", "--steps", "10", "--out", "x", "--config", "attention.yaml"],
     "the training env has observation version 1: set env: {observation: {version: 2}}"),
    (["train", "mappo", "office", "--steps", "10", "--out", "x", "--config", "bad_env.yaml"], "nope"),
])
def test_bad_arguments_one_line_exit_2(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "attention.yaml").write_text("critic: attention\n")
    (tmp_path / "bad_env.yaml").write_text("env: {nope: 1}\n")
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("parcover") and words in err[0]
    assert not (tmp_path / "x").exists()  # nothing written


@pytest.mark.parametrize("backend", ["local", "ray"])
def test_train_then_bench_the_sidecar_policy(backend, tmp_path, capsys):
    pytest.importorskip("torchrl")
    if backend == "ray":
        pytest.importorskip("ray")
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text("frames_per_batch: 64\nminibatch_size: 32\nepochs: 1\nhidden: [8]\nepisode_steps: 40\n")
    out = tmp_path / "run"
    argv = ["train", "ippo", "office", "--steps", "100", "--out", str(out), "--backend", backend, "--seed", "2",
            "--config", str(cfg)]
    assert main(argv) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["command"] == "parcover " + " ".join(argv)
    assert record["agent_steps"] == 128 and record["config"]["episode_steps"] == 40
    assert record["backend"] == backend and record["init"] is None
    assert f"--policies {record['policy']}" in capsys.readouterr().out
    code = main(["bench", "office", "--policies", record["policy"], "--seeds", "2", "--max-steps", "30",
                 "--workers", "1", "--out", str(tmp_path / "bench"), "--no-plots", "--quiet"])
    assert code == 0 and record["policy"] in (tmp_path / "bench" / "table.md").read_text()


def test_init_from_a_run_and_from_a_misfit_network(tmp_path, capsys):
    pytest.importorskip("torchrl")
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text("frames_per_batch: 64\nminibatch_size: 32\nepochs: 1\nhidden: [8]\nepisode_steps: 40\n")
    first, second = tmp_path / "first", tmp_path / "second"
    assert main(["train", "ippo", "office", "--steps", "100", "--out", str(first), "--config", str(cfg)]) == 0
    argv = ["train", "ippo", "office", "--steps", "100", "--out", str(second), "--config", str(cfg),
            "--init", str(first)]
    assert main(argv) == 0
    record = json.loads((second / "run.json").read_text())
    assert record["init"] == {"path": str(first), "algo": "ippo", "init": None, "critic": True}
    assert record["command"].endswith(f"--init {first}")
    assert f"started from {first} and its critic" in capsys.readouterr().out
    wide = tmp_path / "wide.yaml"
    wide.write_text(cfg.read_text().replace("hidden: [8]", "hidden: [16]"))
    assert main(["train", "ippo", "office", "--steps", "100", "--out", str(tmp_path / "third"), "--config",
                 str(wide), "--init", str(first / "policy.pt")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "hidden [8]" in err[0] and "does not fit this run's" in err[0] and "hidden [16]" in err[0]
    assert not (tmp_path / "third" / "run.json").exists()


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["local", "ray"])
def test_issue_done_when_train_ippo_office_4096_then_bench(backend, tmp_path, monkeypatch):
    """The issue's check as written: ``parcover train ippo office --steps 4096`` (default settings), then
    ``parcover bench office --policies <its policy spec> --seeds 2``."""
    pytest.importorskip("torchrl")
    if backend == "ray":
        pytest.importorskip("ray")
    monkeypatch.chdir(tmp_path)
    assert main(["train", "ippo", "office", "--steps", "4096", "--out", "run", "--backend", backend]) == 0
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["agent_steps"] >= 4096 and record["backend"] == backend
    assert main(["bench", "office", "--policies", record["policy"], "--seeds", "2", "--out", "bench",
                 "--no-plots", "--quiet"]) == 0
    assert record["policy"] in (tmp_path / "bench" / "table.md").read_text()


@pytest.mark.parametrize("backend", ["local", "ray"])
def test_rollout_input_scale_reaches_the_collecting_actor(backend, tmp_path, monkeypatch):
    """``obs_scale: rollout`` fits the actor's input scale after the first batch; the actor that collects the
    next batches (a remote one with ``--backend ray``) must use it: the log-probabilities stored with a batch
    are then the learner's own before its first update, so PPO's approximate KL on each batch's first (and
    only) minibatch is ~0 (with the box scale still at the collector it reads ~0.01-0.06)."""
    pytest.importorskip("torchrl")
    if backend == "ray":
        pytest.importorskip("ray")
    from torchrl.objectives.multiagent import IPPOLoss

    kls = []
    forward = IPPOLoss.forward

    def recording(self, td):
        out = forward(self, td)
        kls.append(float(out.get("kl_approx")))
        return out

    monkeypatch.setattr(IPPOLoss, "forward", recording)
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text("frames_per_batch: 64\nminibatch_size: 64\nepochs: 1\nhidden: [8]\nepisode_steps: 40\n"
                   "obs_scale: rollout\n")
    argv = ["train", "ippo", "office", "--steps", "300", "--out", str(tmp_path / "run"), "--backend", backend,
            "--seed", "2", "--config", str(cfg)]
    assert main(argv) == 0
    assert len(kls) >= 2  # the batches after the one that set the scale
    assert max(abs(k) for k in kls) < 1e-5, kls


def test_init_line_names_the_critic_and_the_grown_entries():
    from parcover_env.cli.train import init_line

    base = {"path": "runs/a", "algo": "mappo", "init": None}
    assert init_line({**base, "critic": True}) == "started from runs/a and its critic"
    assert init_line({**base, "critic": False}) == "started from runs/a (critic from scratch: another kind or size)"
    grown = {**base, "critic": False, "grown": {"observation": ["scanning", "scan_result"], "actions": ["scan"]}}
    assert init_line(grown) == ("started from runs/a (critic from scratch: another kind or size); actor grown by "
                                "observation scanning, scan_result; actions scan (new weights zero)")
    only_obs = {**base, "critic": True, "grown": {"observation": ["scanning"], "actions": []}}
    assert init_line(only_obs) == ("started from runs/a and its critic; actor grown by observation scanning "
                                   "(new weights zero)")
