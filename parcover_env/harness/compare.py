"""``parcover_env.compare``: bench a policy of your own beside the expert, from Python.

The episodes are ``parcover bench``'s (:func:`~parcover_env.harness.bench.run_job`'s env, episode
runner and per-episode record) and so is the table: per (scenario, policy) the success rate and the
IQM of every metric with 95 % stratified-bootstrap CIs (:func:`~parcover_env.harness.bench.summarize`).
Your policy is a Policy object, a factory ``(env, seed) -> Policy`` / ``(env) -> Policy``, a Policy
class, or a spec string (``py:MODULE:ATTR``, ``ppo:PATH``, ...); see
:mod:`parcover_env.policies.external`. It drives the scenario as it is (plus the ``env_overrides``
you give, or those its factory carries as ``env_overrides``); the expert drives the env ``parcover
bench`` gives it (with the env's sonar scan service). Every policy's episode ``seed`` starts with
``env.reset(seed=seed)``; a policy that drives as the expert does, on the expert's env, gets the
expert's records bit for bit (wall time aside).

With ``workers > 1`` the episodes run in spawned processes, and the policy is sent to them pickled:
a module-level factory or class pickles (by reference: the worker imports its module), a lambda or
a nested function does not; such a policy, or one whose module the worker cannot import, gets one
error suggesting a module-level factory or a ``py:`` spec. A Policy object is copied into every episode
there; with ``workers=1`` the one object drives every episode in turn (``reset`` before each).
"""

from __future__ import annotations

import pickle
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from parcover_env.errors import ParcoverError

__all__ = ["compare", "Comparison", "run_policy_job"]


@dataclass(frozen=True)
class Comparison:
    """What :func:`compare` returns; ``str()`` of it is the Markdown table."""

    episodes: list[dict]
    """One record per episode (``parcover bench``'s ``EPISODE_FIELDS``), in (scenario, policy, seed) order."""
    summary: list[dict]
    """One row per (scenario, policy): ``success`` (mean) and the IQM of every metric with ``_lo``/``_hi``
    95 % bootstrap bounds (:func:`parcover_env.harness.bench.summarize`)."""
    table: str
    """The summary as ``parcover bench``'s Markdown table."""

    def __str__(self) -> str:
        return self.table

    def row(self, policy: str, scenario: str | None = None) -> dict:
        """The summary row of ``policy`` (on ``scenario``; optional with one scenario)."""
        rows = [r for r in self.summary if r["policy"] == policy and scenario in (None, r["scenario"])]
        if len(rows) != 1:
            found = sorted({(r["scenario"], r["policy"]) for r in self.summary})
            raise KeyError(f"no single summary row for policy {policy!r}, scenario {scenario!r}; rows: {found}")
        return rows[0]


class _Pickled:
    """A policy on its way to a worker process, unpickled there (an error names the policy)."""

    def __init__(self, payload: bytes, label: str):
        self.payload, self.label = payload, label

    def load(self) -> Any:
        try:
            return pickle.loads(self.payload)
        except Exception as exc:
            raise ParcoverError(_unpicklable(self.label, exc, "cannot be unpickled in a worker process")) from None


def _unpicklable(label: str, exc: BaseException, what: str) -> str:
    return (f"policy '{label}' {what} ({type(exc).__name__}: {exc}), so it cannot run with workers > 1: "
            "define a factory (env, seed) -> Policy at module level in an importable module and pass it, "
            "or name it by the spec 'py:MODULE:ATTR', or run with workers=1")


def run_policy_job(scenario: str, label: str, policy: Any, seed: int, max_steps: int | None = None,
                   preset: str = "realistic", env_overrides: dict | None = None) -> dict:
    """One episode of ``policy`` (a Policy object or a factory, see :mod:`parcover_env.policies.external`)
    recorded as ``label``; the record of :func:`~parcover_env.harness.bench.run_job`."""
    from parcover_env.harness.bench import bench_env, episode_record
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.external import policy_from
    from parcover_env.policies.registry import fitting_policy

    if isinstance(policy, _Pickled):
        policy = policy.load()
    env = bench_env(scenario, max_steps, preset, env_overrides)
    driver = fitting_policy(policy_from(policy, env, seed, label), env, label)
    return episode_record(scenario, label, preset, seed, run_episode(env, driver, seed))


def _label(policy: Any) -> str:
    if isinstance(policy, str):
        return policy
    name = getattr(policy, "__name__", None) if callable(policy) else None
    return name or type(policy).__name__


def _seeds(seeds: Iterable[int]) -> list[int]:
    if isinstance(seeds, int | str):
        raise ParcoverError(f"seeds must be a sequence of episode seeds, e.g. range(1000, 1010), got {seeds!r}")
    out = list(seeds)
    bad = [s for s in out if isinstance(s, bool) or not isinstance(s, int) or s < 0]
    if bad or not out:
        raise ParcoverError(f"seeds must be one or more integers >= 0, got {out!r}")
    return out


def compare(
    policy: Any | dict[str, Any],
    scenarios: str | Sequence[str],
    seeds: Iterable[int],
    *,
    workers: int = 1,
    name: str | None = None,
    against: Sequence[str] = ("expert",),
    env_overrides: dict | None = None,
    max_steps: int | None = None,
    preset: str = "realistic",
    backend: str = "local",
    progress: bool = False,
) -> Comparison:
    """Run ``policy`` beside ``against`` (registry specs, default the expert) on every scenario and
    seed; the per-episode records, the summary and ``parcover bench``'s table.

    ``policy``: a Policy object, a factory ``(env, seed) -> Policy`` or ``(env) -> Policy``, a Policy
    class, or a spec string (``py:MODULE:ATTR``, ``ppo:PATH``, ...); or a mapping ``{name: policy}``
    of several, benched in one sweep. ``scenarios``: names, YAML paths
    or ``generated:SEED`` (one string or several). ``seeds``: the episode seeds (the same for every
    policy). ``name``: the policy's row label (default: the spec, or the factory's or class's
    ``__name__``). ``env_overrides``: scenario overrides of your policy's env (default: the factory's
    ``env_overrides`` attribute, else none). ``max_steps``: cut every episode there (default: the
    scenario's limit). ``workers > 1``: episodes in that many processes (the policy must pickle, see the
    module docstring); ``backend="ray"`` as ``parcover bench --backend ray``. One ParcoverError for bad
    input."""
    from parcover_env.harness.bench import markdown_table, run_calls, run_job, summarize
    from parcover_env.policies.registry import check_policy_spec

    scenario_list = [scenarios] if isinstance(scenarios, str) else list(scenarios)
    if not scenario_list or not all(isinstance(s, str) and s for s in scenario_list):
        raise ParcoverError(f"scenarios must be one or more scenario names or paths, got {scenarios!r}")
    seed_list = _seeds(seeds)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParcoverError(f"workers must be an integer >= 1, got {workers!r}")
    if backend not in ("local", "ray"):
        raise ParcoverError(f"backend must be 'local' or 'ray', got {backend!r}")
    if max_steps is not None and (isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1):
        raise ParcoverError(f"max_steps must be an integer >= 1 or None, got {max_steps!r}")
    if isinstance(against, str):
        against = [against]
    for spec in against:
        check_policy_spec(spec)
    if env_overrides is not None and not isinstance(env_overrides, dict):
        raise ParcoverError(f"env_overrides must be a mapping, got {type(env_overrides).__name__}")
    if isinstance(policy, dict):
        if name is not None:
            raise ParcoverError("name= labels a single policy; the keys of a mapping of policies are their names")
        if not policy or not all(isinstance(k, str) and k for k in policy):
            raise ParcoverError(f"a mapping of policies needs one or more names (str) as keys, got {list(policy)!r}")
        named = list(policy.items())
    else:
        named = [(name or _label(policy), policy)]
    for label, _ in named:
        if label in against:
            raise ParcoverError(f"policy name '{label}' is also a baseline in against={list(against)}: give "
                                "another name")

    own = {s: [] for s in scenario_list}
    for label, one in named:
        for s in scenario_list:
            own[s] += _jobs(label, one, s, seed_list, workers, backend, max_steps, preset, env_overrides)
    calls = []
    for s in scenario_list:  # per scenario: the baselines, then the policies (the table's row order)
        calls += [(run_job, (s, spec, seed, max_steps, preset)) for spec in against for seed in seed_list] + own[s]
    rows = run_calls(_call, calls, workers, backend, progress)
    summary = summarize(rows)
    return Comparison(rows, summary, markdown_table(summary))


def _jobs(label: str, policy: Any, scenario: str, seeds: list[int], workers: int, backend: str,
          max_steps: int | None, preset: str, env_overrides: dict | None) -> list[tuple]:
    """The calls of one policy's episodes on one scenario."""
    from parcover_env.policies.external import env_overrides_of
    from parcover_env.policies.registry import check_policy_spec

    if isinstance(policy, str):  # a registry spec: run as ``parcover bench`` runs it
        check_policy_spec(policy)
        return [(_spec_job, (label, scenario, policy, seed, max_steps, preset)) for seed in seeds]
    overrides = env_overrides if env_overrides is not None else env_overrides_of(policy, label)
    sent = policy
    if workers > 1 and backend == "local":
        try:
            sent = _Pickled(pickle.dumps(policy), label)
        except Exception as exc:
            raise ParcoverError(_unpicklable(label, exc, "does not pickle")) from None
    return [(run_policy_job, (scenario, label, sent, seed, max_steps, preset, overrides)) for seed in seeds]


def _call(fn, args: tuple) -> dict:
    return fn(*args)


def _spec_job(label: str, scenario: str, spec: str, seed: int, max_steps: int | None, preset: str) -> dict:
    """``parcover bench``'s episode of a registry spec, recorded as ``label``."""
    from parcover_env.harness.bench import run_job

    return {**run_job(scenario, spec, seed, max_steps, preset), "policy": label}
