"""``parcover train --init PATH``: start a run from a previous run's networks.

``PATH`` is a ``parcover train`` output directory or its ``policy.pt``. The actor always starts from
that ``policy.pt`` (weights and observation box); it must have this run's observation size, hidden
widths and action size, else one :class:`~parcover_env.errors.ParcoverError`. The critic starts from
the ``critic.pt`` beside it when that critic has this run's :func:`critic_spec` (same algorithm,
critic kind, input sizes, widths and value normalization, whose running statistics come with it),
else from scratch. The new run's sidecar records :func:`init_record`: the path, the init run's own
``algo`` and ``init`` (from its ``run.json``; ``None`` for a bare ``policy.pt``) and whether the critic
was loaded, so a chain of runs says how its last network was made.

With ``init_grow: true`` the run's env may add observation entries and action components that the
init's env lacked (e.g. the ``scan`` ones): the init env is rebuilt from the init run's sidecar
(:func:`init_env_args`) and the actor is grown by name (:mod:`~parcover_env.harness.marl_grow`); the
``init`` record then says ``grown: {observation: [...], actions: [...]}`` (the new entries and
components). A critic of another input size starts from scratch, as above.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from parcover_env.errors import CheckpointError, ParcoverError
from parcover_env.harness.marl_config import MarlConfig
from parcover_env.harness.marl_grow import Growth, grow_actor
from parcover_env.policies.checkpoint_files import first_line
from parcover_env.policies.torchrl_policy import POLICY_FILE, TorchRLPolicy, head_act_dim

__all__ = ["CRITIC_FILE", "InitSource", "find_init", "init_env_args", "critic_spec", "save_critic", "apply_init"]

CRITIC_FILE = "critic.pt"
"""The critic checkpoint beside ``policy.pt``: ``spec`` (:func:`critic_spec`), ``state_dict``, ``value_norm``."""


@dataclass(frozen=True)
class InitSource:
    """What ``--init PATH`` points at."""

    path: str
    """As given."""
    policy: Path
    critic: Path | None
    """``critic.pt`` beside the policy, if there is one."""
    run: dict | None
    """The init run's sidecar ``run.json``, if there is one."""


def find_init(path: str | Path) -> InitSource:
    """The checkpoint files of ``path`` (a run directory or its ``policy.pt``), or a ParcoverError."""
    given = Path(path)
    policy = given / POLICY_FILE if given.is_dir() else given
    if not policy.is_file():
        raise ParcoverError(f"--init {path}: no such file {policy} (expected a parcover train output directory "
                            f"or its {POLICY_FILE})")
    sidecar, critic = policy.parent / "run.json", policy.parent / CRITIC_FILE
    run = None
    if sidecar.is_file():
        try:
            run = json.loads(sidecar.read_text())
        except (OSError, ValueError) as exc:
            raise ParcoverError(f"--init {path}: cannot read {sidecar}: {exc}") from None
        if not isinstance(run, dict):
            raise ParcoverError(f"--init {path}: {sidecar} is not a JSON object")
    return InitSource(str(path), policy, critic if critic.is_file() else None, run)


def init_env_args(src: InitSource) -> dict:
    """The :class:`~parcover_env.harness.marl.EnvMaker` keyword arguments (``scenario``, ``preset``,
    ``overrides``, ``max_robots``) of the init run's env, from its sidecar; ParcoverError without one."""
    run = src.run
    config = run.get("config") if run else None
    if not run or not isinstance(run.get("scenario"), str) or not isinstance(config, dict):
        raise ParcoverError(f"--init {src.path}: init_grow needs the init run's run.json (scenario and config) "
                            "to rebuild its env's observation layout")
    overrides = run.get("env_overrides", config.get("env"))
    return {"scenario": run["scenario"], "preset": config.get("preset", "realistic"),
            "overrides": overrides or None, "max_robots": int(config.get("max_robots", 12))}


def critic_spec(algo: str, cfg: MarlConfig, obs_dim: int, state_dim: int) -> dict:
    """What a saved critic must match to be loaded: its kind, input sizes, widths, value normalization."""
    kind = cfg.critic if algo == "mappo" else "mlp"
    spec = {"algo": algo, "critic": kind, "obs_dim": obs_dim, "state_dim": state_dim if algo == "mappo" else 0,
            "hidden": list(cfg.hidden), "value_norm": cfg.value_norm}
    if kind == "attention":
        spec.update(embed=cfg.critic_embed, heads=cfg.critic_heads)
    if algo == "ippo" and cfg.obs_scale != "box":  # IPPO's critic then has the actor's input scale
        spec.update(obs_scale=cfg.obs_scale)
    return spec


def save_critic(path: Path, critic, value_norm, spec: dict) -> None:
    """Write ``critic.pt``: the critic's weights, the value normalizer's statistics and ``spec``."""
    import torch

    torch.save({"spec": spec, "state_dict": critic.state_dict(),
                "value_norm": value_norm.state_dict() if value_norm is not None else None}, path)


def _shape(net, scan_head: str) -> tuple[int, list[int], int, str]:
    """(observation size, hidden widths, action size, scan head) of an :func:`actor_net` of ``scan_head``."""
    import torch

    linear = [m for m in net if isinstance(m, torch.nn.Linear)]
    return (linear[0].in_features, [m.out_features for m in linear[:-1]],
            head_act_dim(linear[-1].out_features, scan_head), scan_head)


def apply_init(src: InitSource, actor_net, critic, value_norm, spec: dict, growth: Growth | None = None,
               scan_head: str = "continuous") -> dict:
    """Load ``src`` into ``actor_net`` (an :func:`actor_net` with ``scan_head``, required to match
    unless ``growth``, with ``init_grow``, says how the two envs' layouts differ; the init's scan head
    is its file's) and, when its spec equals ``spec``, into ``critic`` and ``value_norm``; returns the
    sidecar's ``init`` record."""
    import dataclasses

    import torch

    policy = TorchRLPolicy(src.policy)  # a corrupt or foreign file is a ParcoverError naming it
    loaded = policy.net
    grown = None
    if growth is not None:
        growth = dataclasses.replace(growth, init_io=dataclasses.replace(growth.init_io, scan_head=policy.scan_head))
    if growth is not None and growth.changes:
        grown = grow_actor(src.path, loaded, actor_net, growth)
    else:
        theirs, ours = _shape(loaded, policy.scan_head), _shape(actor_net, scan_head)
        if theirs != ours:
            def show(s):
                return f"observation {s[0]}, hidden {s[1]}, actions {s[2]}, scan head {s[3]}"

            hint = "" if growth is not None else " (init_grow: true grows it into new observation entries/actions)"
            raise ParcoverError(f"--init {src.path}: its actor ({show(theirs)}) does not fit this run's "
                                f"({show(ours)}){hint}")
        actor_net.load_state_dict(loaded.state_dict())
    critic_loaded = False
    if src.critic is not None:
        try:
            ckpt = torch.load(src.critic, map_location="cpu", weights_only=True)
        except Exception as exc:  # a corrupt file: name it
            raise ParcoverError(f"--init {src.path}: cannot load {src.critic}: {type(exc).__name__}: {exc}") from None
        if isinstance(ckpt, dict) and ckpt.get("spec") == spec:
            try:
                critic.load_state_dict(ckpt["state_dict"])
                if value_norm is not None and ckpt.get("value_norm") is not None:
                    value_norm.load_state_dict(ckpt["value_norm"])
            except (KeyError, TypeError, ValueError, RuntimeError) as exc:  # its spec matches, its weights do not
                raise CheckpointError(src.critic, "critic", f"its weights do not fit its spec ({first_line(exc)})"
                                      ) from None
            critic_loaded = True
    run = src.run or {}
    record = {"path": src.path, "algo": run.get("algo"), "init": run.get("init"), "critic": critic_loaded}
    if grown is not None:
        record["grown"] = grown
    return record
