"""``parcover train`` on the batched env: the config fields, the env maker (local and Ray workers), a run."""

from __future__ import annotations

import dataclasses

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from parcover_env.errors import ConfigError  # noqa: E402
from parcover_env.harness.marl import EnvMaker, TrainRequest, train  # noqa: E402
from parcover_env.harness.marl_config import MarlConfig, load_marl_config  # noqa: E402
from parcover_env.train.batched_env import BatchedRobotsEnv  # noqa: E402

V2 = {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}


@pytest.mark.parametrize(("text", "key", "words"), [
    ("collector_env: parallel\n", "collector_env", "batched"),
    ("worlds: 4\nworlds_per_map: 3\n", "worlds_per_map", "must divide worlds (4)"),
    ("worlds_per_map: 0\n", "worlds_per_map", "> 0"),
])
def test_bad_collector_settings_name_file_and_key(tmp_path, text, key, words):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_marl_config("ippo", path)
    assert err.value.source == str(path) and err.value.key == key and words in str(err.value)


def test_defaults_collect_batched_one_map_per_world():
    assert (MarlConfig().collector_env, MarlConfig().worlds_per_map) == ("batched", 1)
    assert load_marl_config("mappo").collector_env == "batched"


def test_the_maker_builds_the_batched_env_and_rebuilds_itself_for_ray_workers():
    maker = EnvMaker("generated:3-6", "realistic", 5, seed=2, overrides=V2, max_robots=6, worlds=4, state=False,
                     collector_env="batched", worlds_per_map=2)
    env = maker()
    assert isinstance(env.base_env, BatchedRobotsEnv) and env.batch_size == (4,)
    assert env.base_env.worlds.n_groups == 2 and env.base_env.worlds.cfg.episode_steps == 5
    twin = EnvMaker(seed=2, **maker.args())()
    assert (env.reset() == twin.reset()).all()  # a Ray worker's maker builds the same env
    td = env.rollout(5, break_when_any_done=False)
    assert td["next", "robot", "episode_reward"].shape == (4, 5, 6, 1)
    assert td["next", "done"][:, -1].all() and not td["next", "done"][:, :-1].any()


def test_a_batched_run_counts_only_real_robots_and_matches_itself(tmp_path):
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=64, minibatch_size=32, epochs=1,
                              hidden=(8,), episode_steps=6, worlds=4, worlds_per_map=2, max_robots=6, env=V2)
    seen = []

    def on_batch(batch, collect_s, update_s):
        pad = batch.get(("robot", "info", "pad"))
        seen.append((tuple(batch.shape), int((1.0 - pad).sum().item()), batch.get(("robot", "observation")).sum()))
        return False

    record = train(TrainRequest("ippo", "generated:3-6", 200, tmp_path / "a", cfg, "x", seed=3), on_batch=on_batch)
    assert [s[0] for s in seen] == [(4, 16)] * len(seen) and record["agent_steps"] == sum(s[1] for s in seen)
    assert record["agent_steps"] >= 200 and all(0 < s[1] < 4 * 16 * 6 for s in seen)  # padding left out
    again = []
    train(TrainRequest("ippo", "generated:3-6", 200, tmp_path / "b", cfg, "x", seed=3),
          on_batch=lambda b, c, u: again.append(b.get(("robot", "observation")).sum()) and False)
    assert again == [s[2] for s in seen]  # same seed, same collection
    assert record["config"]["collector_env"] == "batched" and record["config"]["worlds_per_map"] == 2
