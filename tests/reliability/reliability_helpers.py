"""Shared helpers of the reliability tests: env snapshots, scripted rollouts (also run in spawned
child processes, so everything here is importable and picklable)."""

from __future__ import annotations

import numpy as np

import parcover_env as pe


def snapshot(env) -> dict:
    """Everything that defines where an episode stands (for exact comparisons)."""
    return {
        "steps": env.steps,
        "time": env.world.time,
        "poses": env.world.poses(),
        "estimate": np.array(env.estimate, copy=True),
        "commands": np.array(env.commands, copy=True),
        "visited": np.array(env.progress.visited, copy=True),
        "rng": repr(env._rng.bit_generator.state),
        "agents": list(env.agents),
    }


def assert_same_snapshot(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        if isinstance(a[k], np.ndarray):
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
        else:
            assert a[k] == b[k], k


def step_record(out) -> tuple:
    """A step's return value as comparable arrays: (obs stack, rewards, terminated, truncated)."""
    obs, rew, term, trunc, _ = out
    agents = sorted(obs)
    stack = np.stack([obs[a] for a in agents]) if agents else np.zeros((0,))
    return (stack, np.array([rew[a] for a in sorted(rew)]), tuple(sorted(term.items())),
            tuple(sorted(trunc.items())))


def assert_same_records(ra: list, rb: list) -> None:
    assert len(ra) == len(rb)
    for i, (a, b) in enumerate(zip(ra, rb, strict=True)):
        np.testing.assert_array_equal(a[0], b[0], err_msg=f"obs at step {i}")
        np.testing.assert_array_equal(a[1], b[1], err_msg=f"rewards at step {i}")
        assert a[2:] == b[2:], f"done flags at step {i}"


def random_actions(agents, rng: np.random.Generator, scale: float = 1.0) -> dict:
    return {a: (scale * rng.uniform(-1.0, 1.0, 2)).astype(np.float32) for a in agents}


def continue_rollout(env, action_seed: int, steps: int) -> list:
    """Step ``env`` with seeded random actions (resetting without a seed when an episode ends)."""
    rng = np.random.default_rng(action_seed)
    out = []
    for _ in range(steps):
        if not env.agents:
            env.reset()
        out.append(step_record(env.step(random_actions(env.agents, rng))))
    return out


def rollout(scenario: str, overrides: dict | None, seeds: tuple, steps: int) -> list:
    """Fresh env; for each seed: reset(seed) then ``steps`` random steps. Runs in child processes."""
    env = pe.parallel_env(scenario, overrides=overrides)
    out = []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        out.append((np.stack([obs[a] for a in sorted(obs)]), None, (), ()))
        out += continue_rollout(env, action_seed=seed, steps=steps)
    return out
