"""The training-throughput instrument of issue 40 (``benchmarks/train_throughput.py``) and the trainer's
``on_batch`` hook it times through: per-batch seconds, stopping, the collection split, the medians, one table."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from parcover_env.harness.marl import TrainRequest, train  # noqa: E402
from parcover_env.harness.marl_config import load_marl_config  # noqa: E402

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "train_throughput.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("train_throughput_under_test", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_import_has_no_side_effects(capsys):
    spec = importlib.util.spec_from_file_location("train_throughput_import", SCRIPT)
    spec.loader.exec_module(importlib.util.module_from_spec(spec))
    assert capsys.readouterr() == ("", "")


def test_on_batch_gets_each_batch_with_its_seconds_and_can_stop_the_run(tmp_path):
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=32, minibatch_size=32, epochs=1,
                              hidden=(8,), episode_steps=20, obs_scale="rollout",
                              env={"observation": {"version": 2}})
    calls = []

    def on_batch(batch, collect_s, update_s):
        calls.append((batch.numel(), batch.get(("robot", "observation")).shape[-2], collect_s, update_s))
        return len(calls) == 3

    record = train(TrainRequest("ippo", "office", 10 * 32 * 2, tmp_path / "a", cfg, "x"), on_batch=on_batch)
    assert len(calls) == 3  # stopped by the hook, not by the 10-batch budget
    assert [(n, robots) for n, robots, _, _ in calls] == [(32, 2)] * 3  # office: 2 robots
    assert record["agent_steps"] == 3 * 32 * 2
    assert all(c > 0 for _, _, c, _ in calls)
    assert calls[0][3] == 0.0 and calls[1][3] > 0 and calls[2][3] > 0  # the first batch only fits the scale


def test_collection_split_sorts_samples_by_what_runs(bench):
    site = "/venv/lib/python3.11/site-packages/"

    def stack(*frames):
        return [f"{fn}\x00{path}\x001" for fn, path in frames]

    collect = [("train", "/r/parcover_env/harness/marl.py"), ("iterator", site + "torchrl/collectors/_single.py"),
               ("rollout", site + "torchrl/collectors/_single.py")]
    step = [("_step", site + "torchrl/envs/batched_envs.py"), ("_step", "/r/parcover_env/harness/marl_env.py"),
            ("step", "/r/parcover_env/harness/map_pool.py"), ("step", "/r/parcover_env/envs/parallel.py")]
    records = [
        (stack(*collect, *step, ("update", "/r/parcover_env/localization/sonar/mcl.py"),
               ("cast", "/r/parcover_env/sensors/rays.py")), 0.5),  # the localizer with what it calls
        (stack(*collect, *step, ("mean", site + "numpy/_core/fromnumeric.py")), 0.2),  # env core
        (stack(*collect, ("forward", site + "tensordict/nn/common.py"),
               ("forward", site + "torch/nn/modules/linear.py")), 0.1),  # the actor
        (stack(*collect, ("_step", site + "torchrl/envs/batched_envs.py"), ("stack", site + "tensordict/_td.py"),
               ("helper", site + "torch/_tensor.py")), 0.1),  # TorchRL's own (torch called by tensordict)
        (stack(*collect, *step[:2]), 0.05),  # the adapter itself
        (stack(*collect, ("wait", "/usr/lib/python3.11/threading.py")), 0.05),  # the collector's own
        (stack(("train", "/r/parcover_env/harness/marl.py"), ("backward", site + "torch/_tensor.py")), 3.0),
    ]
    split = bench.collection_split(records)
    want = {"localizer": 0.5, "policy": 0.1, "adapter": 0.05, "env": 0.2, "TorchRL": 0.15}
    assert split == pytest.approx(want)
    assert bench.collection_split(records[-1:]) == {}  # no collection sample: nothing to split


def test_medians_per_column(bench):
    batches = [{"steps": 1000.0, "frames": 100.0, "collect_s": 1.0, "update_s": 0.25},   # 1000, 4000, 800; 100
               {"steps": 1000.0, "frames": 100.0, "collect_s": 0.5, "update_s": 0.5},    # 2000, 2000, 1000; 200
               {"steps": 2000.0, "frames": 400.0, "collect_s": 4.0, "update_s": 1.0}]    # 500, 2000, 400; 100
    assert bench.medians(batches) == pytest.approx({"collect": 1000.0, "update": 2000.0, "loop": 800.0,
                                                    "worlds": 100.0})


def test_one_table_with_every_row_and_the_target(bench, capsys):
    assert bench.main(["--frames", "32", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    rows, idle, worlds = {}, {}, {}
    for line in out.splitlines():
        if m := re.match(r"^(pool (?:no )?scan(?: grouped| serial)?|vmas navigation) +(\d+) +(\d+) +(\d+) +"
                         r"(?:[\d.]+x|n/a) +(\d+%|-) +(\d+) ", line):
            rows[m[1]] = [float(x) for x in m.group(2, 3, 4)]
            idle[m[1]], worlds[m[1]] = m[5], float(m[6])
    pool = {f"pool {s}{k}" for s in ("scan", "no scan") for k in ("", " grouped", " serial")}
    assert pool <= set(rows) and all(min(v) > 0 for v in rows.values())
    assert all(re.fullmatch(r"\d+%", idle[r]) for r in pool) and idle.get("vmas navigation", "-") == "-"
    for r in pool:  # 1-12 real robots per world-step (no idle world in a fresh 32-frame batch); printed rounded
        assert worlds[r] - 1 <= rows[r][0] <= 12 * (worlds[r] + 1)
    for collect, update, loop in rows.values():  # the loop's time is the sum of the two (one batch: no median)
        assert 1 / loop == pytest.approx(1 / collect + 1 / update, rel=0.03)  # printed rounded
    assert re.search(r"^pool scan .*(NOT met|met) \(\d+%\); VMAS: ", out, re.M)
    assert "frames/batch" in out and "32 frames/batch" in out and "load average" in out
    if importlib.util.find_spec("vmas") is None:
        assert "vmas navigation: SKIPPED, vmas is not installed" in out
    else:
        assert "vmas navigation" in rows and re.search(r"^vmas navigation .* 1\.00x", out, re.M)
    split = re.search(r"collection split of its warm-up batch: (.*)$", out, re.M).group(1)
    if importlib.util.find_spec("pyinstrument") is None:
        assert split == "not sampled: pyinstrument is not installed (pip install 'parcover_env[bench]')"
    else:
        shares = dict((k, int(v)) for k, v in re.findall(r"(\w+) (\d+)%", split))
        assert set(shares) == {"localizer", "policy", "adapter", "env", "TorchRL"}
        # every share is a whole percent of the warm-up batch; the localizer's may round to 0 % when the
        # fresh actor's 32 frames hold few scans (its classification is pinned by the test above)
        assert 97 <= sum(shares.values()) <= 103 and all(0 <= v <= 100 for v in shares.values())
    assert 0 <= int(re.search(r"scan requested on (\d+)% of real robot-steps", out).group(1)) <= 100
