"""Hyper-parameters of ``parcover train`` (IPPO, MAPPO), one YAML per algorithm in ``configs/train/``.

:class:`MarlConfig` is a frozen typed dataclass filled by the project's config loader
(:func:`parcover_env.config.from_mapping`): an unknown key, a wrong type or a value out of range is
one :class:`~parcover_env.errors.ConfigError` naming the file and the key. Every field is a knob of a
TorchRL component (named beside it); the trainer only passes them on.

The defaults of ``parcover train`` are the files ``configs/train/ippo.yaml`` and ``mappo.yaml``, which set
every PPO key (the recipe that learned office, each value's source in a comment). The dataclass defaults
below only fill keys a file leaves out; they stay as they were so that the configs of earlier runs, which
rely on them, keep their meaning.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from parcover_env.config import from_mapping, read_yaml
from parcover_env.errors import ConfigError

__all__ = ["MarlConfig", "ALGOS", "default_config_path", "load_marl_config", "scheduled_lr"]

ALGOS = ("ippo", "mappo")
"""The algorithms ``parcover train`` knows: IPPO (per-agent critic), MAPPO (centralized critic)."""


@dataclass(frozen=True)
class MarlConfig:
    """PPO settings, collected and optimized by TorchRL (agent-steps = env steps x robots)."""

    frames_per_batch: int = 1024
    """Env steps per collected batch (``Collector(frames_per_batch=...)``); each holds every robot."""
    epochs: int = 4
    """Passes over each batch."""
    minibatch_size: int = 256
    """Env steps per gradient step (``ReplayBuffer(batch_size=...)``, sampled without replacement)."""
    learning_rate: float = 3e-4
    """Adam step size for actor and critic (at the start of the run when ``lr_end`` is set)."""
    lr_end: float | None = None
    """Linear learning-rate decay: the step size goes from ``learning_rate`` to this value over the
    run's budget, the larger of the fractions of ``--steps`` and of ``wall_time`` used, set before
    each batch's updates (:func:`scheduled_lr`). None: constant ``learning_rate``."""
    critic_warmup: int = 0
    """Agent-steps at the start of the run during which only the critic learns (the actor's loss is
    left out), e.g. when ``--init`` brings an actor but no critic. 0: none."""
    init_grow: bool = False
    """``--init`` into an env with observation entries or action components the init's env lacked
    (e.g. ``observation.scan.enabled``): the actor is grown by name
    (:mod:`~parcover_env.harness.marl_grow`). False: an actor of another size is an error."""
    init_grow_loc: float = -1.5
    """``init_grow``: the ``loc`` of a new action component (zero weights): its deterministic action
    is ``tanh(init_grow_loc)`` (-0.905: for ``scan``, read as "scan when > 0", no scan). A new
    ``bernoulli`` scan head starts at the logit of the same sampled scan probability,
    ``P(N(init_grow_loc, init_grow_std) > 0)`` (-6.61 at the defaults)."""
    init_grow_std: float = 0.5
    """``init_grow``: the TanhNormal scale of a new action component at the start."""
    scan_head: Literal["bernoulli", "continuous"] = "bernoulli"
    """How the actor outputs the ``scan`` action component when the env has the scan service
    (``observation.scan.enabled``; without it the actor is the TanhNormal of ``(v, omega)`` whatever
    this says): ``bernoulli``, a Bernoulli "scan now" beside the TanhNormal of ``(v, omega)``, whose
    deterministic action scans where its probability is above 0.5
    (:mod:`~parcover_env.harness.marl_scan_head`); ``continuous``, a third TanhNormal component read
    as "scan when > 0" (the head of the shipped stage 6-7 checkpoints). A grown ``bernoulli`` scan
    starts with the scan probability ``init_grow_loc`` / ``init_grow_std`` give a grown ``continuous``
    one."""
    max_grad_norm: float = 0.5
    """Gradients are clipped to this global norm."""
    gamma: float = 0.99
    """Discount (``MultiAgentGAE(gamma=...)``)."""
    gae_lambda: float = 0.95
    """GAE lambda (``MultiAgentGAE(lmbda=...)``)."""
    clip_epsilon: float = 0.2
    """PPO ratio clip (``ClipPPOLoss(clip_epsilon=...)``)."""
    entropy_coeff: float = 0.0
    """Entropy bonus weight."""
    critic_coeff: float = 1.0
    """Critic loss weight."""
    value_norm: Literal["popart", "running", "none"] = "popart"
    """Value-target normalization: ``PopArtValueNorm`` (MAPPO paper), ``RunningValueNorm`` or none."""
    normalize_advantage: bool = True
    """Standardize advantages per minibatch (over time, not across robots)."""
    obs_scale: Literal["box", "rollout"] = "box"
    """Input scale of the actor (and of IPPO's critic): ``box`` scales each observation entry by the
    env's observation box to [-1, 1]; ``rollout`` by the mean and standard deviation of the first
    batch's observations, which is not learned from (:mod:`~parcover_env.harness.marl_scale`; a run
    with ``--init`` keeps the init's scale)."""
    hidden: tuple[int, ...] = (128, 128)
    """Hidden layer widths of the actor and the critic (tanh MLPs, shared by every robot)."""
    critic: Literal["mlp", "attention"] = "mlp"
    """MAPPO's critic: ``mlp`` on ``cat(state, obs_i)`` (any env version), or ``attention`` on the
    version-2 state tokens (:class:`~parcover_env.harness.token_critic.TokenCritic`, permutation-
    invariant, one network for every map; needs ``env: {observation: {version: 2}}``). IPPO: ``mlp``."""
    critic_embed: int = 64
    """``critic: attention``: token embedding width."""
    critic_heads: int = 4
    """``critic: attention``: attention heads (must divide ``critic_embed``)."""
    episode_steps: int = 0
    """Step limit of a training episode (0: the scenario's ``episode.max_steps``): the TorchRL env
    truncates there while the env keeps the scenario's limit, so the ``time`` observation means the
    same in training and evaluation (:class:`~parcover_env.harness.marl_env.RobotsEnv`)."""
    wall_time: float = 0.0
    """Stop after the batch that ends past this many seconds of wall time (0: no limit); the run
    is saved as if ``--steps`` had been reached (the sidecar's ``agent_steps`` is what was done)."""
    preset: Literal["realistic", "ideal"] = "realistic"
    """Error models of the training env."""
    env: dict[str, Any] = field(default_factory=dict)
    """Scenario overrides of the training env, merged over the scenario as the env's ``overrides``
    (e.g. ``{observation: {version: 2}, rewards: {own_kpoi: 10.0, kpoi: 1.0}}`` for ``parcover_v2``);
    written into the sidecar (``env_overrides``) so that the policy's spec builds the same env."""
    max_robots: int = 12
    """Agents of a map pool (``generated:A-B``): each map's robots, padded to this count
    (:class:`~parcover_env.harness.map_pool.MapPoolEnv`)."""
    worlds: int = 1
    """Worlds collected side by side in one process (each its own generator): the policy runs once for
    all of them. ``frames_per_batch`` counts the env steps of all worlds (each world runs
    ``frames_per_batch / worlds`` steps per batch)."""
    collector_env: Literal["batched", "serial"] = "batched"
    """How the worlds are collected: ``batched``, one TorchRL env of batch ``[worlds]`` on the batched
    stepper (:class:`~parcover_env.train.batched_env.BatchedRobotsEnv`: arrays to tensors, ``worlds /
    worlds_per_map`` stepper calls per step; every episode reset with a seed drawn by its group);
    ``serial``, TorchRL's ``SerialEnv`` of one PettingZoo env per world
    (:class:`~parcover_env.harness.marl_env.RobotsEnv`; world ``k`` seeded once), how runs collected
    before the batched env (set it to replay one of their seeds)."""
    worlds_per_map: int = 1
    """``collector_env: batched`` on a map pool: worlds that run one drawn map together (must divide
    ``worlds``): a group draws its next map when all its worlds' episodes have ended, a world that ends
    earlier idles until then (padding: not learned from, not counted). 1: every world draws its own
    maps, as ``serial`` does; larger: fewer, larger stepper calls, fewer maps per batch."""
    checkpoint_every: float = 0.0
    """Save the run (policy, critic, curve, sidecar) after the batch that ends past every this many
    seconds of wall time since the last save (0: only at the end)."""
    mask_done: bool = False
    """Leave robots whose own route is done (version 2 ``info["route_done"]``, the env docstring's
    death mask) out of the PPO loss as padding is (their actions still apply; their rewards still
    count in their earlier steps' returns). Default off: every robot's steps are learned from."""
    ray_collectors: int = 1
    """``--backend ray``: remote collectors (``RayCollector(num_collectors=...)``), one env each (seeds
    SEED, SEED + 1, ...); each collects ``frames_per_batch / ray_collectors`` env steps of every batch."""

    def check(self, source: str) -> MarlConfig:
        """Self, or ConfigError naming ``source`` and the first out-of-range key."""
        positive = ("frames_per_batch", "epochs", "minibatch_size", "learning_rate", "max_grad_norm", "clip_epsilon",
                    "ray_collectors", "critic_embed", "critic_heads", "max_robots", "worlds", "worlds_per_map")
        if not self.init_grow_std > 0.01:  # the actor's scale floor (NormalParamExtractor's biased softplus)
            raise ConfigError(source, "init_grow_std", f"must be > 0.01, got {self.init_grow_std}")
        for key in positive:
            if not getattr(self, key) > 0:
                raise ConfigError(source, key, f"must be > 0, got {getattr(self, key)}")
        for key in ("gamma", "gae_lambda"):
            if not 0.0 <= getattr(self, key) <= 1.0:
                raise ConfigError(source, key, f"must be in [0, 1], got {getattr(self, key)}")
        for key in ("entropy_coeff", "critic_coeff", "episode_steps", "wall_time", "checkpoint_every", "critic_warmup"):
            if getattr(self, key) < 0:
                raise ConfigError(source, key, f"must be >= 0, got {getattr(self, key)}")
        if self.lr_end is not None and not 0.0 <= self.lr_end <= self.learning_rate:
            raise ConfigError(source, "lr_end", f"must be in [0, learning_rate ({self.learning_rate})], "
                              f"got {self.lr_end}")
        if self.minibatch_size > self.frames_per_batch:
            raise ConfigError(source, "minibatch_size", f"must be <= frames_per_batch ({self.frames_per_batch}), "
                              f"got {self.minibatch_size}")
        if self.frames_per_batch % self.ray_collectors:
            raise ConfigError(source, "ray_collectors", f"must divide frames_per_batch ({self.frames_per_batch}), "
                              f"got {self.ray_collectors}")
        if self.frames_per_batch % (self.ray_collectors * self.worlds):
            raise ConfigError(source, "worlds", f"worlds x ray_collectors ({self.worlds} x {self.ray_collectors}) "
                              f"must divide frames_per_batch ({self.frames_per_batch})")
        if self.worlds % self.worlds_per_map:
            raise ConfigError(source, "worlds_per_map",
                              f"must divide worlds ({self.worlds}), got {self.worlds_per_map}")
        if not self.hidden or min(self.hidden) < 1:
            raise ConfigError(source, "hidden", f"expected one or more widths >= 1, got {list(self.hidden)}")
        if self.critic_embed % self.critic_heads:
            raise ConfigError(source, "critic_heads", f"must divide critic_embed ({self.critic_embed}), "
                              f"got {self.critic_heads}")
        return self

    def check_critic(self, algo: str, version: int, source: str, pool: bool = False) -> None:
        """ConfigError naming ``source`` if the critic does not fit ``algo`` or an env of observation
        ``version`` (``critic: attention`` reads the version-2 state tokens, and only MAPPO has a state critic;
        MAPPO on a map pool (``pool``) needs version 2's ``state()``, the one of the same shape on every map)."""
        if algo == "mappo" and pool and version != 2:
            raise ConfigError(source, "env.observation.version", f"MAPPO's critic reads env.state(), whose shape "
                              f"under observation version {version} differs from map to map of a pool: set env: "
                              "{observation: {version: 2}} (a state of one shape) or train ippo")
        if self.critic != "attention":
            return
        if algo != "mappo":
            raise ConfigError(source, "critic", f"attention is MAPPO's critic on env.state(); {algo}'s critic sees "
                              "only the robot's observation: use critic: mlp")
        if version != 2:
            raise ConfigError(source, "critic", f"attention reads the version-2 state tokens, but the training env "
                              f"has observation version {version}: set env: {{observation: {{version: 2}}}}")


def scheduled_lr(cfg: MarlConfig, agent_steps: int, steps: int, elapsed: float) -> float:
    """The step size after ``agent_steps`` of ``steps`` and ``elapsed`` seconds: ``learning_rate``, or
    with ``lr_end`` set the linear interpolation to it by the used fraction of the budget (the larger
    of ``agent_steps / steps`` and ``elapsed / wall_time``, at most 1)."""
    if cfg.lr_end is None:
        return cfg.learning_rate
    used = agent_steps / steps if steps > 0 else 0.0
    if cfg.wall_time:
        used = max(used, elapsed / cfg.wall_time)
    used = min(1.0, used)
    return cfg.learning_rate + (cfg.lr_end - cfg.learning_rate) * used


def default_config_path(algo: str) -> Path:
    """``configs/train/ALGO.yaml``: of the source checkout, else of the installed package."""
    from parcover_env.scenarios.registry import configs_dir

    return configs_dir() / "train" / f"{algo}.yaml"


def load_marl_config(algo: str, path: str | Path | None = None) -> MarlConfig:
    """The settings of ``algo`` from ``path`` (default: :func:`default_config_path`)."""
    path = Path(path) if path is not None else default_config_path(algo)
    source = str(path)
    if not path.is_file():
        raise ConfigError(source, "", "no such file")
    data = read_yaml(path)
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(source, "", f"expected a mapping of settings, got {type(data).__name__}")
    return from_mapping(MarlConfig, data, source).check(source)
