"""One registry of policies by spec string: expert, waypoint, random, ppo:PATH, bc:PATH, mappo:PATH."""

from __future__ import annotations

from pathlib import Path

from parcover_env.errors import ParcoverError

__all__ = ["BASIC_POLICIES", "POLICY_SPECS", "make_policy", "check_policy_spec"]

BASIC_POLICIES = ("expert", "waypoint", "random")
POLICY_SPECS = "expert | waypoint | random | ppo:PATH | bc:PATH | mappo:PATH"
LEARNED_KINDS = ("ppo", "bc", "mappo")


def make_policy(spec: str, env, seed: int | None):
    """A policy object with ``act(observations) -> actions`` from a spec string."""
    kind, _, path = spec.partition(":")
    if kind == "random":
        from parcover_env.policies.simple import RandomPolicy

        return RandomPolicy(seed)
    if kind == "waypoint":
        from parcover_env.policies.simple import WaypointPolicy

        return WaypointPolicy(env.layout)
    if kind == "expert":
        from parcover_env.expert.policy import ScriptedExpert

        return ScriptedExpert.for_env(env)
    if kind in LEARNED_KINDS:
        if not path:
            raise ParcoverError(f"policy '{spec}': give a checkpoint, e.g. {kind}:runs/{kind}_office")
        check_policy_spec(spec)
        from parcover_env.errors import require

        torch = require("torch", "train", f"policy '{spec}'")
        if kind == "ppo":
            require("stable_baselines3", "train", f"policy '{spec}'", package="stable-baselines3")
        from parcover_env.policies.learned import BCPolicy, PPOPolicy

        torch.set_num_threads(1)  # small MLPs: one thread is fastest and avoids oversubscribing workers

        policy = PPOPolicy(path) if kind == "ppo" else BCPolicy(path, "actor.pt" if kind == "mappo" else "bc.pt")
        expected = env.observation_space(env.possible_agents[0]).shape
        if tuple(policy.obs_shape) != tuple(expected):
            raise ParcoverError(f"policy '{spec}' was trained on observations of shape {tuple(policy.obs_shape)}; "
                                f"scenario '{env.scenario.name}' gives {tuple(expected)}")
        return policy
    raise ParcoverError(
        f"unknown policy '{spec}' (choose from {', '.join(BASIC_POLICIES)}, ppo:PATH, bc:PATH, mappo:PATH)"
    )


def check_policy_spec(spec: str) -> None:
    kind, _, path = spec.partition(":")
    if kind in BASIC_POLICIES and not path:
        return
    if kind in LEARNED_KINDS and path:
        if not Path(path).exists():
            raise ParcoverError(f"policy '{spec}': {path} does not exist")
        return
    raise ParcoverError(
        f"unknown policy '{spec}' (choose from {', '.join(BASIC_POLICIES)}, ppo:PATH, bc:PATH, mappo:PATH)"
    )
