"""configs/train/{ippo,mappo}.yaml load into MarlConfig and are the recipe that learned office;
configs/train/ holds only what the results name; bad files name the file and the key."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import pytest

from parcover_env.errors import ConfigError
from parcover_env.harness.marl_config import ALGOS, MarlConfig, default_config_path, load_marl_config

ROOT = Path(__file__).resolve().parents[2]
TRAIN = ROOT / "configs" / "train"
LAB_CONFIGS = ROOT / "docs" / "lab" / "train_configs"
V2 = {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}


@pytest.mark.parametrize("algo", ALGOS)
def test_shipped_configs_load(algo):
    cfg = load_marl_config(algo)
    assert default_config_path(algo).name == f"{algo}.yaml"
    assert cfg.gamma == 0.99 and cfg.entropy_coeff == 0.001 and cfg.gae_lambda == 0.95
    assert cfg.value_norm == "popart" and cfg.env == V2 and cfg.critic == "mlp"
    assert cfg.hidden == (128, 128) and cfg.frames_per_batch % cfg.minibatch_size == 0


@pytest.mark.parametrize("algo", ALGOS)
def test_defaults_are_the_recipe_that_learned_office(algo):
    """The default of `parcover train ALGO` is ippo_office_scratch.yaml (the shipped office baseline's
    config, recorded in its sidecar) but for its wall-time cap: the run's length is --steps."""
    recipe = load_marl_config("ippo", TRAIN / "ippo_office_scratch.yaml")
    sidecar = json.loads((ROOT / "baselines/checkpoints/ippo_office_scratch/run.json").read_text())
    assert load_marl_config("ippo", TRAIN / "ippo_office_scratch.yaml") == MarlConfig(
        **{**sidecar["config"], "hidden": tuple(sidecar["config"]["hidden"])})
    cfg = load_marl_config(algo)
    assert (recipe.wall_time, cfg.wall_time) == (2700.0, 0.0)
    assert cfg == dataclasses.replace(recipe, wall_time=0.0)


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
    cfg = load_marl_config("mappo", LAB_CONFIGS / "mappo_attention.yaml")
    assert (cfg.critic, cfg.critic_embed, cfg.critic_heads) == ("attention", 64, 4)
    assert cfg.env == {"observation": {"version": 2}}
    assert load_marl_config("mappo").critic == "mlp" and load_marl_config("mappo").env == V2
    (tmp_path / "a.yaml").write_text("env: {episode: {max_steps: 500}}\n")
    assert load_marl_config("ippo", tmp_path / "a.yaml").env == {"episode": {"max_steps": 500}}


def test_configs_train_holds_only_the_defaults_and_what_the_results_name():
    """configs/train/ keeps ippo.yaml, mappo.yaml and the configs of the runs the README's and the results
    page's rows name (the last stage of each row's checkpoint); staged history is in docs/lab/train_configs/."""
    named = (ROOT / "README.md").read_text() + (ROOT / "docs" / "results.md").read_text()
    kept = sorted(p.stem for p in TRAIN.glob("*.yaml"))
    assert {"ippo", "mappo"} <= set(kept)
    for stem in set(kept) - {"ippo", "mappo"}:
        assert f"`{stem}`" in named, f"configs/train/{stem}.yaml is named by no results row"
    for stem in ("ippo_generated_shaped", "mappo_generated_attention"):  # staged history, moved
        assert not (TRAIN / f"{stem}.yaml").exists() and (LAB_CONFIGS / f"{stem}.yaml").is_file()


def test_every_config_a_shipped_sidecar_names_is_found():
    """Each ``config_file`` in a shipped TorchRL sidecar (and its ``init_run`` chain) is in configs/train/ or,
    for staged history, under the same name in docs/lab/train_configs/, with the values the run recorded."""
    def chain(run):
        while run:
            yield run
            run = run.get("init_run")

    seen = 0
    for sidecar in sorted((ROOT / "baselines" / "checkpoints").glob("*/run.json")):
        for run in chain(json.loads(sidecar.read_text())):
            name = Path(run["config_file"]).name
            path = TRAIN / name if (TRAIN / name).is_file() else LAB_CONFIGS / name
            assert path.is_file(), f"{sidecar}: {run['config_file']} is in neither place"
            loaded = load_marl_config(run["algo"], path)
            for key, value in run["config"].items():
                assert getattr(loaded, key) == (tuple(value) if key == "hidden" else value), (path, key)
            seen += 1
    assert seen >= 7


def test_moved_configs_name_their_new_place():
    """The usage comments of the moved configs give the path they live at now."""
    for path in LAB_CONFIGS.glob("*.yaml"):
        assert not re.search(r"configs/train/" + path.stem + r"\.yaml", path.read_text()), path
