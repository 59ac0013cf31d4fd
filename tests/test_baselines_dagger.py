"""baselines/dagger.py: the driver schedule, the teacher's labels in the learner's states, the rounds."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

def _waypoint_labels(env, obs: np.ndarray) -> np.ndarray:
    from parcover_env.policies.simple import WaypointPolicy

    pol = WaypointPolicy(env.layout)
    return np.stack([pol.act({"r": o})["r"] for o in obs])


def test_driver_schedule_needs_round_zero_without_a_network(load_baseline):
    dagger = load_baseline("dagger")
    assert dagger.driver_schedule("0,0.5,1") == [0.0, 0.5, 1.0]
    for bad in ("0.5,1", "0,1.5", "0,-0.1", ""):
        with pytest.raises(ValueError, match="driver_probs"):
            dagger.driver_schedule(bad)


@pytest.fixture(scope="module")
def dagger_run(tmp_path_factory, load_baseline):
    dagger = load_baseline("dagger")
    out = tmp_path_factory.mktemp("dagger")
    args = dagger.parse_args(["--n-maps", "1", "--map-seed0", "3", "--driver-probs", "0,1", "--max-steps", "60",
                              "--workers", "1", "--bc-epochs", "2", "--net-arch", "16",
                              "--val-scenarios", "generated:500", "--out", str(out)])
    dagger.run(args)
    return dagger, args, out


def test_rounds_are_labelled_by_the_teacher_where_the_learner_drives(dagger_run):
    from parcover_env.envs import ParallelCoverageEnv

    dagger, args, out = dagger_run
    env = ParallelCoverageEnv("generated:3")
    eps = dagger.collect_round(args, 1, f"ppo:{out / 'round_0' / 'model.zip'}", 1.0)
    obs = np.concatenate([e["observations"][:-1] for e in eps])
    act = np.concatenate([e["actions"] for e in eps])
    # every recorded action is the waypoint controller's answer in the recorded state ...
    np.testing.assert_allclose(act, _waypoint_labels(env, obs), atol=1e-6)
    # ... while the states are the learner's (it drove every step): not the teacher's own rollout
    own = dagger.collect_round(args, 1, None, 0.0)
    assert not np.allclose(np.concatenate([e["observations"] for e in own]), np.concatenate(
        [e["observations"] for e in eps]))
    assert {e["seed"] for e in eps} == {100} and len(eps) == 3  # 3 robots; round 1, map 0: seed0 + 100 r + k


def test_best_round_is_shipped_with_history_and_sidecars(dagger_run):
    _, _, out = dagger_run
    side = json.loads((out / "model.json").read_text())
    hist = side["history"]
    assert [h["round"] for h in hist] == [0, 1] and hist[1]["samples"] > hist[0]["samples"]
    scores = [(h["val_kpoi_fraction"], h["val_success"]) for h in hist]
    assert side["best_round"] == max(range(2), key=lambda r: (scores[r], -r))
    assert side["command"].startswith("python baselines/dagger.py") and "--driver-probs" in side["command"]
    r1 = json.loads((out / "round_1" / "model.json").read_text())
    assert r1["driver_prob"] == 1.0 and r1["driver"].endswith("round_0/model.zip")
    assert r1["validation"][0]["seed"] == 500
    assert (out / "model.zip").read_bytes() == (out / f"round_{side['best_round']}" / "model.zip").read_bytes()
