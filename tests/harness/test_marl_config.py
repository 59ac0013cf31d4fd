"""configs/train/{ippo,mappo}.yaml load into MarlConfig; bad files name the file and the key."""

from __future__ import annotations

import pytest

from parcover_env.errors import ConfigError
from parcover_env.harness.marl_config import ALGOS, MarlConfig, default_config_path, load_marl_config


@pytest.mark.parametrize("algo", ALGOS)
def test_shipped_configs_load(algo):
    cfg = load_marl_config(algo)
    assert default_config_path(algo).name == f"{algo}.yaml"
    assert cfg.gamma == 0.995 and cfg.gae_lambda == 0.95 and cfg.value_norm == "popart"
    assert cfg.hidden == (128, 128) and cfg.frames_per_batch % cfg.minibatch_size == 0


@pytest.mark.parametrize(("text", "key", "words"), [
    ("gama: 0.9\n", "gama", "gamma"),
    ("gamma: 1.5\n", "gamma", "[0, 1]"),
    ("value_norm: popsicle\n", "value_norm", "popart"),
    ("minibatch_size: 2048\nframes_per_batch: 1024\n", "minibatch_size", "<= frames_per_batch"),
    ("learning_rate: 0\n", "learning_rate", "> 0"),
    ("hidden: []\n", "hidden", "widths"),
    ("ray_collectors: 3\n", "ray_collectors", "divide frames_per_batch"),
    ("critic: gnn\n", "critic", "attention"),
    ("critic_embed: 30\ncritic_heads: 4\n", "critic_heads", "divide critic_embed (30)"),
    ("critic_heads: 0\n", "critic_heads", "> 0"),
    ("env: [1]\n", "env", "mapping"),
    ("learning_rate: 1.0e-4\nlr_end: 2.0e-4\n", "lr_end", "[0, learning_rate"),
    ("lr_end: -1.0e-5\n", "lr_end", "[0, learning_rate"),
    ("critic_warmup: -1\n", "critic_warmup", ">= 0"),
])
def test_bad_values_name_file_and_key(tmp_path, text, key, words):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_marl_config("ippo", path)
    assert err.value.source == str(path) and err.value.key == key and words in str(err.value)


def test_missing_file_and_empty_file(tmp_path):
    with pytest.raises(ConfigError, match="no such file"):
        load_marl_config("ippo", tmp_path / "none.yaml")
    (tmp_path / "empty.yaml").write_text("")
    assert load_marl_config("ippo", tmp_path / "empty.yaml") == MarlConfig()


def test_attention_config_and_env_overrides(tmp_path):
    cfg = load_marl_config("mappo", default_config_path("mappo").with_name("mappo_attention.yaml"))
    assert (cfg.critic, cfg.critic_embed, cfg.critic_heads) == ("attention", 64, 4)
    assert cfg.env == {"observation": {"version": 2}}
    assert load_marl_config("mappo").critic == "mlp" and load_marl_config("mappo").env == {}
    (tmp_path / "a.yaml").write_text("env: {episode: {max_steps: 500}}\n")
    assert load_marl_config("ippo", tmp_path / "a.yaml").env == {"episode": {"max_steps": 500}}
