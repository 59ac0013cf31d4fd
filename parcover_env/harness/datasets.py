"""Expert demonstrations: record episodes, per agent, and store them as a Minari dataset.

Minari datasets are single-agent, so each robot's trajectory is stored as its own episode
(the parameter-sharing view the baselines train on): observations ``(T+1, obs_dim)``, actions
``(T, 2)``, the robot's rewards, terminations and truncations. Minari (``pip install
'parcover_env[data]'`` plus ``h5py``) is imported lazily; :func:`record_episodes` needs no extra.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from parcover_env.errors import ParcoverError

__all__ = ["AgentEpisode", "record_episodes", "save_minari", "load_minari", "load_minari_many", "dataset_ids",
           "collect"]


class AgentEpisode(dict):
    """One robot's trajectory: keys observations, actions, rewards, terminations, truncations, seed."""


def record_episodes(
    scenario: Any, episodes: int, seed: int = 0, policy: str = "expert", max_steps: int | None = None,
    preset: str = "realistic", driver: str | None = None, driver_prob: float = 1.0,
    overrides: dict | None = None,
) -> list[AgentEpisode]:
    """Run ``episodes`` episodes (seeds ``seed .. seed+episodes-1``) under ``preset``; one AgentEpisode
    per robot. ``policy`` labels every step (the recorded actions); without ``driver`` it also acts.

    With ``driver`` (a policy spec, e.g. ``ppo:runs/x/model.zip``) the team executes the driver's
    actions on a fraction ``driver_prob`` of the steps (drawn per step from a generator seeded with
    the episode seed) and the labeller's on the others, while the recorded actions stay the
    labeller's: DAgger's data (Ross et al. 2011), the expert's answer in the states the learner
    reaches. The labeller runs on every step, so a stateful expert tracks the real trajectory.

    ``overrides``: scenario overrides of the env (e.g. a training config's ``env`` mapping), under
    ``max_steps``."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if not 0.0 <= driver_prob <= 1.0:
        raise ValueError(f"driver_prob must be in [0, 1], got {driver_prob}")
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.policies.registry import make_policy

    if max_steps:
        from parcover_env.config import deep_merge

        overrides = deep_merge(overrides or {}, {"episode": {"max_steps": max_steps}})
    env = ParallelCoverageEnv(scenario, overrides=overrides, preset=preset)
    out: list[AgentEpisode] = []
    for k in range(episodes):
        ep_seed = seed + k
        pol = make_policy(policy, env, ep_seed)
        drv = make_policy(driver, env, ep_seed) if driver else None
        coin = np.random.default_rng(ep_seed)
        obs, _ = env.reset(seed=ep_seed)
        for p in (pol, drv):
            if p is not None:
                p.reset(obs)
        traj = {
            a: {"observations": [obs[a]], "actions": [], "rewards": [], "terminations": [], "truncations": []}
            for a in env.possible_agents
        }
        while env.agents:
            actions = pol.act(obs)
            executed = actions
            if drv is not None:
                driven = drv.act(obs)
                if coin.random() < driver_prob:
                    executed = driven
            live = list(env.agents)
            obs, rew, term, trunc, _ = env.step(executed)
            for a in live:
                t = traj[a]
                t["actions"].append(np.clip(np.asarray(actions[a], np.float32), -1, 1))
                t["observations"].append(obs[a])
                t["rewards"].append(rew[a])
                t["terminations"].append(term[a])
                t["truncations"].append(trunc[a])
        for a in env.possible_agents:
            t = traj[a]
            if not t["actions"]:
                continue
            out.append(
                AgentEpisode(
                    observations=np.asarray(t["observations"], np.float32),
                    actions=np.asarray(t["actions"], np.float32),
                    rewards=np.asarray(t["rewards"], np.float64),
                    terminations=np.asarray(t["terminations"], bool),
                    truncations=np.asarray(t["truncations"], bool),
                    seed=ep_seed,
                    agent=a,
                )
            )
    return out


def _minari():
    from parcover_env.errors import require

    minari = require("minari", "data", "Minari datasets")
    require("h5py", "data", "Minari datasets")
    return minari


def dataset_path(dataset_id: str, root: str | Path) -> Path:
    """Where Minari keeps dataset ``dataset_id`` under ``root`` (MINARI_DATASETS_PATH)."""
    return Path(root) / dataset_id


def save_minari(
    episodes: list[AgentEpisode],
    dataset_id: str,
    out: str | Path,
    scenario: Any,
    algorithm: str = "ScriptedExpert",
) -> Path:
    """Write the episodes as Minari dataset ``dataset_id`` under ``out`` (MINARI_DATASETS_PATH)."""
    if not episodes:
        raise ValueError("no episodes to save")
    minari = _minari()
    from minari.data_collector import EpisodeBuffer

    from parcover_env.envs import ParallelCoverageEnv

    env = ParallelCoverageEnv(scenario)
    agent = env.possible_agents[0]
    os.environ["MINARI_DATASETS_PATH"] = str(Path(out).resolve())
    buffers = [
        EpisodeBuffer(
            id=i,
            seed=int(e["seed"]),
            observations=e["observations"],
            actions=e["actions"],
            rewards=list(e["rewards"]),
            terminations=list(e["terminations"]),
            truncations=list(e["truncations"]),
            infos={},
        )
        for i, e in enumerate(episodes)
    ]
    import warnings

    with warnings.catch_warnings():  # Minari warns about optional metadata (author e-mail, permalink)
        warnings.simplefilter("ignore", UserWarning)
        _create(minari, dataset_id, buffers, algorithm, env, agent)
    return Path(out) / dataset_id


def _create(minari, dataset_id, buffers, algorithm, env, agent) -> None:
    minari.create_dataset_from_buffers(
        dataset_id,
        buffers,
        algorithm_name=algorithm,
        author="parcover_env",
        observation_space=env.observation_space(agent),
        action_space=env.action_space(agent),
        env=_env_spec(env),
        description=f"{algorithm} demonstrations on scenario '{env.scenario.name}', one episode per robot "
        "(parameter sharing view)",
        data_format="hdf5",
    )


def _env_spec(env):
    """The Gymnasium spec of the one-robot view of the scenario, so ``dataset.recover_environment()``
    can rebuild an env (``parcover_env/SingleRobotCoverage-v0`` with the scenario and a 1-robot team)."""
    from gymnasium.envs.registration import EnvSpec

    from parcover_env.scenarios import configs_dir

    source = env.scenario.source
    if Path(source).parent == configs_dir():  # a shipped scenario: by name, not by this machine's path
        source = Path(source).stem
    return EnvSpec(
        id="parcover_env/SingleRobotCoverage-v0",
        entry_point="parcover_env.envs.single_agent:SingleRobotCoverageEnv",
        max_episode_steps=env.scenario.episode.max_steps,
        kwargs={"scenario": source, "overrides": {"n_robots": 1}},
    )


def load_minari(dataset_id: str, root: str | Path) -> list[AgentEpisode]:
    """Read a dataset written by :func:`save_minari` back as AgentEpisodes."""
    minari = _minari()
    os.environ["MINARI_DATASETS_PATH"] = str(Path(root).resolve())
    ds = minari.load_dataset(dataset_id)
    return [
        AgentEpisode(
            observations=np.asarray(e.observations, np.float32),
            actions=np.asarray(e.actions, np.float32),
            rewards=np.asarray(e.rewards),
            terminations=np.asarray(e.terminations),
            truncations=np.asarray(e.truncations),
            seed=None,
        )
        for e in ds.iterate_episodes()
    ]


def dataset_ids(spec: str, root: str | Path) -> list[str]:
    """The dataset ids named by ``spec``: comma-separated ids, each may hold ``*``/``?`` wildcards
    matched against the datasets under ``root`` (e.g. ``parcover/generated-*-expert-v0``), sorted."""
    import fnmatch

    root = Path(root)
    ids: list[str] = []
    for part in (p.strip() for p in spec.split(",")):
        if not part:
            continue
        if any(c in part for c in "*?["):
            found = sorted(
                str(d.relative_to(root)) for d in root.glob(part) if d.is_dir() and (d / "data").is_dir()
            )
            found = [f for f in found if fnmatch.fnmatch(f, part)]
            if not found:
                raise ParcoverError(f"no Minari dataset under {root} matches '{part}'")
            ids += found
        else:
            if not dataset_path(part, root).is_dir():
                raise ParcoverError(f"no Minari dataset '{part}' under {root} (write one with parcover collect)")
            ids.append(part)
    if not ids:
        raise ParcoverError(f"no dataset ids in '{spec}'")
    return ids


def load_minari_many(spec: str, root: str | Path) -> list[AgentEpisode]:
    """Every agent-episode of the datasets :func:`dataset_ids` names, in id order."""
    out: list[AgentEpisode] = []
    for ds_id in dataset_ids(spec, root):
        out += load_minari(ds_id, root)
    return out


def collect(
    scenario: str,
    episodes: int,
    out: str | Path,
    seed: int = 0,
    dataset_id: str | None = None,
    policy: str = "expert",
    driver: str | None = None,
    driver_prob: float = 1.0,
    max_steps: int | None = None,
) -> tuple[str, int]:
    """Record and save; returns (dataset id, number of agent-episodes). ``driver``/``driver_prob``:
    see :func:`record_episodes` (default id then ``parcover/<scenario>-<policy>-dagger-v0``)."""
    name = str(scenario).replace(":", "-").replace("/", "-").removesuffix(".yaml")
    dataset_id = dataset_id or f"parcover/{name}-{policy}{'-dagger' if driver else ''}-v0"
    if dataset_path(dataset_id, out).exists():
        raise ParcoverError(f"dataset '{dataset_id}' already exists under {out}; choose another --dataset-id "
                            "or --out, or delete it")
    _minari()  # fail before recording, not after
    eps = record_episodes(scenario, episodes, seed, policy, max_steps=max_steps, driver=driver, driver_prob=driver_prob)
    algorithm = f"{policy} labels, driven by {driver} on {driver_prob:.0%} of steps" if driver else policy
    save_minari(eps, dataset_id, out, scenario, algorithm=algorithm)
    return dataset_id, len(eps)
