"""``parcover train``: IPPO and MAPPO with parameter sharing, through TorchRL's maintained parts.

What is TorchRL's, not ours: the worlds are one TorchRL env of batch ``[worlds]`` on the batched
stepper (``collector_env: batched``, :class:`~parcover_env.train.batched_env.BatchedRobotsEnv`; or
``serial``, ``SerialEnv`` of one :class:`~parcover_env.harness.marl_env.RobotsEnv` per world) with
per-robot observation, reward, ``terminated`` and ``truncated`` and ``env.state()`` under ``"state"``; episode
returns come from ``RewardSum``; ``Collector`` (``--backend local``) or ``RayCollector`` on Ray
core (``--backend ray``: a local Ray, or the cluster at ``--ray-address``; ``ray_collectors``
remote collectors, each with its own env seed, receive the new weights before every batch) collects;
``IPPOLoss`` / ``MAPPOLoss`` (``ClipPPOLoss`` with ``MultiAgentGAE``) compute advantages and
value targets: a truncated step bootstraps from the value of its next state, a terminated one does
not, and the collector resets the env after either. ``PopArtValueNorm`` / ``RunningValueNorm``
normalize the value targets; a ``ReplayBuffer`` without replacement serves the minibatches.

The two algorithms differ only in the critic. IPPO (de Witt et al. 2020): each robot's value of
its own observation. MAPPO (Yu et al. 2022): one critic on the global state ``env.state()`` and the
robot's own observation (the MAPPO paper's agent-specific global state): ``critic: mlp`` on their
concatenation (its size read from ``env.state_space``), or ``critic: attention``, the permutation-
invariant :class:`~parcover_env.harness.token_critic.TokenCritic` on the version-2 state tokens (one
network for every map). Actor and critic are each one network shared by every robot. Settings:
:class:`~parcover_env.harness.marl_config.MarlConfig` (``configs/train/``; its ``env`` mapping
overrides the scenario, e.g. the observation version). A run saves the actor (``policy.pt``) and
the critic with the value normalizer's statistics (``critic.pt``); ``--init`` starts from them
(:mod:`~parcover_env.harness.marl_init`). The actor is a TanhNormal over the action; with the env's
scan service its ``scan`` component is a separate Bernoulli head (``scan_head: bernoulli``, the
default; :mod:`~parcover_env.harness.marl_scan_head`), named in ``policy.pt`` and the sidecar.

torch, torchrl and ray are imported inside the functions (``pip install 'parcover_env[train]'``).
"""

from __future__ import annotations

import functools
import json
import math
import time
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from parcover_env.harness.map_pool import is_pool
from parcover_env.harness.marl_config import MarlConfig, scheduled_lr
from parcover_env.harness.marl_grow import ACTION_COMPONENTS, Growth, env_io
from parcover_env.harness.marl_init import CRITIC_FILE, apply_init, critic_spec, find_init, init_env_args, save_critic
from parcover_env.harness.marl_loss import GROUP, REAL, build_loss, prepare_minibatch, standardize_advantage
from parcover_env.harness.marl_scale import fit_scale
from parcover_env.harness.training import git_commit, plot_curve, write_csv
from parcover_env.policies.torchrl_policy import POLICY_FILE, SIDECAR_FILE, actor_net, box_scale, head_act_dim

__all__ = ["TrainRequest", "EnvMaker", "build_actor", "run_scan_head", "save_policy", "policy_net", "build_critic",
           "critic_scale", "build_loss",
           "train", "GROUP", "REAL", "standardize_advantage", "prepare_minibatch", "RunWriter"]

CURVE_FILE = "curve.csv"


@dataclass(frozen=True)
class TrainRequest:
    """One ``parcover train`` run."""

    algo: str
    scenario: str
    steps: int
    """Agent-steps to collect at least (whole batches: rounded up)."""
    out: Path
    config: MarlConfig
    config_path: str
    backend: str = "local"
    ray_address: str | None = None
    seed: int = 0
    command: str = ""
    init: str | None = None
    """``--init``: a previous run's directory or its ``policy.pt`` (:mod:`~parcover_env.harness.marl_init`)."""


class EnvMaker:
    """Picklable ``() -> TorchRL env`` (Ray workers build their own), plus ``RewardSum`` of each robot's
    reward. ``collector_env="batched"``: the ``worlds`` worlds as one
    :class:`~parcover_env.train.batched_env.BatchedRobotsEnv` (batch ``[worlds]``; its groups' generators
    seeded from ``seed``). ``"serial"``: ``worlds`` copies of the scenario's ParallelEnv, each a
    :class:`~parcover_env.harness.marl_env.RobotsEnv` (with the global state when ``state``), side by
    side in TorchRL's ``SerialEnv`` when ``worlds > 1`` (batch ``[worlds]``: the policy runs once for
    all); with a ``seed``, world 0's generator is seeded ``seed`` and world ``k``'s by
    ``SeedSequence([seed, k])`` before the first reset (every later reset continues that stream: a
    ParallelEnv reset without a seed keeps its generator). Either way torch's generator of the process
    that builds the env, which samples the collector's actions (in a Ray worker too), is seeded ``seed``."""

    def __init__(self, scenario: str, preset: str, episode_steps: int, seed: int | None = None,
                 overrides: dict | None = None, max_robots: int = 12, worlds: int = 1, state: bool = True,
                 mask_done: bool = False, collector_env: str = "serial", worlds_per_map: int = 1):
        self.scenario, self.preset, self.episode_steps, self.seed = scenario, preset, episode_steps, seed
        self.overrides = overrides or None
        """Scenario overrides of the env (``MarlConfig.env``)."""
        self.max_robots = max_robots
        """Agents of a map pool (``generated:A-B``, :class:`~parcover_env.harness.map_pool.MapPoolEnv`)."""
        self.worlds = worlds
        """Worlds stepped side by side (``MarlConfig.worlds``)."""
        self.state = state
        """Whether the env carries ``"state"`` (``env.state()``, MAPPO's critic input)."""
        self.mask_done = mask_done
        """Robots whose route is done are not ``("robot", "real")`` (``MarlConfig.mask_done``)."""
        self.collector_env = collector_env
        """``serial`` (``SerialEnv`` of :class:`~parcover_env.harness.marl_env.RobotsEnv`) or ``batched``
        (:class:`~parcover_env.train.batched_env.BatchedRobotsEnv`), ``MarlConfig.collector_env``."""
        self.worlds_per_map = worlds_per_map
        """Worlds of a map pool that run one drawn map together (``batched``; ``MarlConfig.worlds_per_map``)."""

    def parallel(self):
        """The scenario's PettingZoo ParallelEnv (a map pool's padded env for ``generated:A-B``),
        unwrapped and unseeded."""
        from parcover_env import parallel_env
        from parcover_env.harness.map_pool import MapPoolEnv, is_pool

        kwargs = {"overrides": self.overrides, "preset": self.preset}  # its own step limit (see :meth:`world`)
        if is_pool(self.scenario):
            return MapPoolEnv(self.scenario, self.max_robots, **kwargs)
        return parallel_env(self.scenario, **kwargs)

    def world_seed(self, k: int) -> int | None:
        """The reset seed of world ``k`` (``None`` without a seed)."""
        if self.seed is None or k == 0:
            return self.seed
        return int(np.random.SeedSequence([self.seed, k]).generate_state(1)[0])

    def world(self, k: int = 0):
        """World ``k``: the ParallelEnv, seeded, as a :class:`~parcover_env.harness.marl_env.RobotsEnv`
        that truncates at ``episode_steps`` (the ParallelEnv keeps the scenario's step limit, so its
        ``time`` observation is the fraction of that limit, as in evaluation)."""
        from parcover_env.harness.marl_env import RobotsEnv

        env = self.parallel()
        if self.seed is not None:
            env.reset(seed=self.world_seed(k))
        return RobotsEnv(env, with_state=self.state, max_steps=self.episode_steps, mask_done=self.mask_done)

    def batched(self):
        """The ``worlds`` worlds as one :class:`~parcover_env.train.batched_env.BatchedRobotsEnv` of batch
        ``[worlds]`` (``collector_env: batched``), its groups seeded from ``seed``."""
        from parcover_env.train.batched_env import BatchedRobotsEnv
        from parcover_env.train.world_groups import WorldsConfig

        cfg = WorldsConfig(self.scenario, worlds=self.worlds, worlds_per_map=self.worlds_per_map,
                           max_robots=self.max_robots, overrides=self.overrides, preset=self.preset,
                           episode_steps=self.episode_steps, mask_done=self.mask_done, state=self.state)
        return BatchedRobotsEnv(cfg, seed=self.seed)

    def args(self) -> dict:
        """The keyword arguments that rebuild this maker (but ``seed``)."""
        return {"scenario": self.scenario, "preset": self.preset, "episode_steps": self.episode_steps,
                "overrides": self.overrides, "max_robots": self.max_robots, "worlds": self.worlds,
                "state": self.state, "mask_done": self.mask_done, "collector_env": self.collector_env,
                "worlds_per_map": self.worlds_per_map}

    def __call__(self):
        import torch
        from torchrl.envs import RewardSum, SerialEnv, TransformedEnv

        if self.collector_env == "batched":
            env = self.batched()
        elif self.worlds > 1:
            env = SerialEnv(self.worlds, [functools.partial(self.world, k) for k in range(self.worlds)])
        else:
            env = self.world(0)
        if self.seed is not None:
            torch.manual_seed(self.seed)
        return TransformedEnv(env, RewardSum(in_keys=[(GROUP, "reward")], out_keys=[(GROUP, "episode_reward")]))


def build_actor(obs_low, obs_high, act_dim: int, hidden: tuple[int, ...], scan_head: str = "continuous"):
    """The shared stochastic policy: :func:`actor_net` -> ``NormalParamExtractor`` -> TanhNormal on [-1, 1]
    (``scan_head="continuous"``), or with ``"bernoulli"`` the TanhNormal of ``(v, omega)`` beside a
    Bernoulli scan (:func:`~parcover_env.harness.marl_scan_head.scan_actor`; ``act_dim`` 3)."""
    from tensordict.nn import NormalParamExtractor, TensorDictModule
    from torch import nn
    from torchrl.modules import ProbabilisticActor, TanhNormal

    if scan_head == "bernoulli":
        from parcover_env.harness.marl_scan_head import scan_actor

        return scan_actor(actor_net(obs_low, obs_high, hidden, act_dim, scan_head))
    net = nn.Sequential(actor_net(obs_low, obs_high, hidden, act_dim), NormalParamExtractor())
    module = TensorDictModule(net, in_keys=[(GROUP, "observation")], out_keys=[(GROUP, "loc"), (GROUP, "scale")])
    return ProbabilisticActor(module, in_keys=[(GROUP, "loc"), (GROUP, "scale")], out_keys=[(GROUP, "action")],
                              distribution_class=TanhNormal, distribution_kwargs={"low": -1.0, "high": 1.0},
                              return_log_prob=True)


def run_scan_head(cfg: MarlConfig, act_dim: int) -> str:
    """The scan head of a run whose env has ``act_dim`` action components: ``cfg.scan_head`` with the
    env's scan service (``(v, omega, scan)``), else ``continuous`` (the actor of an env without it is unchanged)."""
    return cfg.scan_head if act_dim == len(ACTION_COMPONENTS) else "continuous"


def policy_net(actor):
    """The :func:`actor_net` inside an actor of :func:`build_actor`."""
    return actor.module[0].module[0]  # TensorDictModule -> Sequential(actor_net, parameter extractor) -> actor_net


def save_policy(actor, path: Path) -> None:
    """Write the actor's network as the ``policy.pt`` that
    :class:`~parcover_env.policies.torchrl_policy.TorchRLPolicy` loads (torch alone, no TorchRL); a
    ``bernoulli`` scan head is named in it (``scan_head``), a ``continuous`` one is not (as before)."""
    import torch

    from parcover_env.harness.marl_scan_head import actor_head

    net, head = policy_net(actor), actor_head(actor)
    linear = [m for m in net if isinstance(m, torch.nn.Linear)]
    ckpt = {"state_dict": net.state_dict(), "obs_dim": linear[0].in_features,
            "hidden": [m.out_features for m in linear[:-1]], "act_dim": head_act_dim(linear[-1].out_features, head)}
    if head != "continuous":
        ckpt["scan_head"] = head
    torch.save(ckpt, path)


def build_critic(algo: str, obs_space, state_space, cfg: MarlConfig):
    """The shared value network: ``(GROUP, "state_value")`` of shape ``[..., robots, 1]``. IPPO reads
    ``(GROUP, "observation")``; MAPPO reads ``"state"`` (broadcast to every robot) and the observation,
    with ``cfg.critic`` ``mlp`` (an MLP on ``cat(state, obs_i)``) or ``attention``
    (:class:`~parcover_env.harness.token_critic.TokenCritic` on the version-2 state tokens).
    ``obs_space`` / ``state_space``: the env's Boxes."""
    import torch
    from tensordict.nn import TensorDictModule
    from torch import nn
    from torchrl.modules import MLP

    class StateAndObservation(nn.Module):
        """``value(cat(state, obs_i))`` for every robot ``i`` with one network."""

        def __init__(self, mlp: nn.Module):
            super().__init__()
            self.mlp = mlp

        def forward(self, state, obs):
            state = state.unsqueeze(-2).expand(*obs.shape[:-1], state.shape[-1])
            return self.mlp(torch.cat([state, obs], dim=-1))

    out = [(GROUP, "state_value")]
    if algo == "mappo" and cfg.critic == "attention":
        from parcover_env.harness.token_critic import TokenCritic

        net = TokenCritic(state_low=state_space.low, state_high=state_space.high, obs_low=obs_space.low,
                          obs_high=obs_space.high, embed=cfg.critic_embed, heads=cfg.critic_heads, hidden=cfg.hidden)
        return TensorDictModule(net, in_keys=["state", (GROUP, "observation")], out_keys=out)
    n_in = obs_space.shape[0] + (state_space.shape[0] if algo == "mappo" else 0)
    mlp = MLP(in_features=n_in, out_features=1, num_cells=list(cfg.hidden), activation_class=nn.Tanh)
    if algo == "mappo":
        return TensorDictModule(StateAndObservation(mlp), in_keys=["state", (GROUP, "observation")], out_keys=out)
    if cfg.obs_scale != "box":  # the actor's input scale in front (fitted with it, :func:`critic_scale`)
        mlp = nn.Sequential(box_scale(obs_space.low, obs_space.high), mlp)
    return TensorDictModule(mlp, in_keys=[(GROUP, "observation")], out_keys=out)


def critic_scale(critic):
    """The input scale module of an IPPO critic of :func:`build_critic` with ``obs_scale`` other than
    ``box``; None for any other critic."""
    from torch import nn

    net = critic.module
    return net[0] if isinstance(net, nn.Sequential) and hasattr(net[0], "half_width") else None


def _collector(req: TrainRequest, make_env: EnvMaker, actor, total_frames: int):
    """TorchRL's single-process ``Collector``, or its ``RayCollector`` with ``ray_collectors`` remote
    collectors (env seeds ``seed + k``) whose batches are stacked (``sync=True``)."""
    cfg = req.config
    if req.backend == "ray":
        from torchrl.collectors.distributed import RayCollector

        k = cfg.ray_collectors
        makers = [EnvMaker(seed=req.seed + i, **make_env.args()) for i in range(k)]  # the same env in every worker
        init = {"address": req.ray_address} if req.ray_address else {"num_cpus": k, "include_dashboard": False}
        init["log_to_driver"] = False  # the workers' warnings would print the collector's repr
        collector = RayCollector(makers, actor, frames_per_batch=cfg.frames_per_batch, total_frames=total_frames,
                                 num_collectors=k, sync=True, ray_init_config=init, remote_configs={"num_cpus": 1},
                                 collector_kwargs={"auto_register_policy_transforms": False},
                                 update_after_each_batch=True)  # the new weights reach the worker before each batch
        collector.update_policy_weights_()  # starts the weight synchronization
    else:
        from torchrl.collectors import Collector

        collector = Collector(make_env, actor, frames_per_batch=cfg.frames_per_batch, total_frames=total_frames,
                              auto_register_policy_transforms=False)  # a feed-forward policy needs none
    return collector


def _episodes(batch) -> list[dict]:
    """Return (mean over the real robots), KPOI fraction and success of every episode that ended in ``batch``."""
    import torch

    nxt = batch.reshape(-1)["next"]  # (time,), or (collectors, time) from RayCollector
    ended = nxt["done"].reshape(-1).nonzero().flatten().tolist()
    nxt = nxt[GROUP]
    out = []
    for t in ended:
        info = nxt["info"][t]
        visited, n_kpois = float(info["metrics/kpois_visited"][0]), float(info["metrics/n_kpois"][0])
        real = (1.0 - info["pad"]) if "pad" in info else torch.ones(info.batch_size)
        returns = nxt["episode_reward"][t].reshape(real.shape)
        out.append({"episode_return": float((returns * real).sum() / real.sum()),
                    "kpoi_fraction": visited / max(n_kpois, 1.0),
                    "success": float(info["metrics/success"][0])})
    return out


class _StopOnSigterm:
    """While installed (main thread only), SIGTERM (``kill PID``, ``timeout``) sets :attr:`requested`:
    the run stops after the current batch and is saved as if ``--steps`` had been reached."""

    def __init__(self):
        import signal
        import threading

        self.requested, self._old = False, None
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGTERM, self._handle)

    def _handle(self, signum, frame) -> None:
        self.requested = True

    def restore(self) -> None:
        import signal

        if self._old is not None:
            signal.signal(signal.SIGTERM, self._old)


def _agent_steps(batch, n_robots: int) -> int:
    """Real robots' steps in ``batch``: env steps x robots, less a map pool's padding (``info["pad"]``)."""
    info = batch.get((GROUP, "info"), None)
    if info is not None and "pad" in info:
        return int((1.0 - info["pad"]).sum().item())
    return batch.numel() * n_robots


def _progress(agent_steps: int, wall: float, ended: list[dict]) -> None:
    """One line per batch that ended episodes: mean return, KPOI fraction and success of those."""
    if ended:
        mean = {k: sum(e[k] for e in ended) / len(ended) for k in ("episode_return", "kpoi_fraction", "success")}
        print(f"{agent_steps} agent-steps {wall:.0f} s: {len(ended)} episodes, return {mean['episode_return']:.2f}, "
              f"KPOI {mean['kpoi_fraction']:.2f}, success {mean['success']:.2f}", flush=True)


def train(req: TrainRequest, on_batch: Callable[[object, float, float], object] | None = None) -> dict:
    """Train, then write ``policy.pt``, ``critic.pt``, ``run.json``, ``curve.csv`` and ``curve.png``
    into ``req.out`` (also every ``checkpoint_every`` seconds of wall time during the run, the files
    replaced whole); returns the sidecar. ``on_batch(batch, collect_s, update_s)``, if given, is called
    after every batch with the seconds spent collecting it and updating on it (GAE and the PPO epochs;
    0.0 for the first batch of an ``obs_scale: rollout`` run, which only fits the input scale); a true
    return stops the run after that batch, as SIGTERM does (``benchmarks/train_throughput.py``)."""
    import torch
    from torchrl.data import LazyTensorStorage, ReplayBuffer
    from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement

    torch.set_num_threads(1)
    torch.manual_seed(req.seed)
    cfg, t0 = req.config, time.perf_counter()
    source = find_init(req.init) if req.init else None  # a bad path fails before the env is built
    make_env = EnvMaker(req.scenario, cfg.preset, cfg.episode_steps, seed=req.seed, overrides=cfg.env,
                        max_robots=cfg.max_robots, worlds=cfg.worlds, state=req.algo == "mappo",
                        mask_done=cfg.mask_done, collector_env=cfg.collector_env, worlds_per_map=cfg.worlds_per_map)
    base = make_env.parallel()  # spaces, robot and KPOI counts
    cfg.check_critic(req.algo, base.scenario.observation.version, req.config_path, pool=is_pool(req.scenario))
    n_robots = base.n_robots
    obs_space, act_dim = base.observation_space(base.possible_agents[0]), base.action_space("robot_0").shape[0]
    head = run_scan_head(cfg, act_dim)
    actor = build_actor(obs_space.low, obs_space.high, act_dim, cfg.hidden, head)
    critic = build_critic(req.algo, obs_space, base.state_space, cfg)
    loss = build_loss(req.algo, cfg, actor, critic)
    spec = critic_spec(req.algo, cfg, obs_space.shape[0], base.state_space.shape[0])
    growth = None
    if source is not None and cfg.init_grow:  # the init's env, rebuilt from its sidecar, for its layout
        init_env = EnvMaker(episode_steps=0, state=False, **init_env_args(source)).parallel()
        growth = Growth(env_io(init_env), env_io(base, head), cfg.init_grow_loc, cfg.init_grow_std)
    init = apply_init(source, policy_net(actor), critic, loss.value_norm, spec, growth, head) if source else None
    optim = torch.optim.Adam(loss.parameters(), lr=cfg.learning_rate)
    # at least one real robot per env step: enough frames for ``req.steps`` real agent-steps; the loop
    # stops at the first batch that reaches them (a map pool's padding robots do not count)
    batches = max(1, math.ceil(req.steps / cfg.frames_per_batch))
    collector = _collector(req, make_env, actor, batches * cfg.frames_per_batch)
    buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames_per_batch), sampler=SamplerWithoutReplacement(),
                          batch_size=cfg.minibatch_size)
    run = RunWriter(req, actor, critic, loss.value_norm, spec, init, n_robots, t0)
    last_save = t0
    stop = _StopOnSigterm()
    fit_pending = cfg.obs_scale == "rollout" and source is None  # an init run keeps its init's scale
    try:
        tick = time.perf_counter()
        for batch in collector:
            collect_s = time.perf_counter() - tick
            run.agent_steps += _agent_steps(batch, n_robots)
            wall = time.perf_counter() - t0
            ended = [{"agent_steps": run.agent_steps, "wall_time": round(wall, 3), **ep} for ep in _episodes(batch)]
            run.rows += ended
            _progress(run.agent_steps, wall, ended)
            if fit_pending:  # the first batch sets the input scale; its log-probs were taken under the box scale
                with torch.no_grad():
                    for scale in (policy_net(actor)[0], critic_scale(critic)):
                        if scale is not None:
                            fit_scale(scale, batch.get((GROUP, "observation")), batch.get(REAL, None))
                fit_pending = False
                if on_batch is not None and on_batch(batch, collect_s, 0.0):
                    break
                tick = time.perf_counter()
                continue
            update_start = time.perf_counter()
            with torch.no_grad(), warnings.catch_warnings():
                # the estimator vmaps the critic over (params, target params); attention has no batching
                # rule there, so torch loops over the two: same values, a "performance drop" warning
                warnings.filterwarnings("ignore", message="There is a performance drop", category=UserWarning)
                loss.value_estimator(batch, params=loss.critic_network_params,
                                     target_params=loss.target_critic_network_params)
            buffer.extend(batch.reshape(-1))
            for group in optim.param_groups:
                group["lr"] = scheduled_lr(cfg, run.agent_steps, req.steps, time.perf_counter() - t0)
            warming = run.agent_steps <= cfg.critic_warmup  # only the critic learns from this batch
            for _ in range(cfg.epochs * (cfg.frames_per_batch // cfg.minibatch_size)):
                parts = loss(prepare_minibatch(loss, buffer.sample(), cfg.normalize_advantage))
                total = parts["loss_critic"]
                if not warming:
                    total = total + parts["loss_objective"] + parts.get("loss_entropy", 0.0)
                optim.zero_grad()
                total.backward()
                torch.nn.utils.clip_grad_norm_(loss.parameters(), cfg.max_grad_norm)
                optim.step()
            halt = on_batch is not None and bool(on_batch(batch, collect_s, time.perf_counter() - update_start))
            if (halt or run.agent_steps >= req.steps or stop.requested
                    or (cfg.wall_time and time.perf_counter() - t0 > cfg.wall_time)):
                break
            if cfg.checkpoint_every and time.perf_counter() - last_save > cfg.checkpoint_every:
                run.save()
                last_save = time.perf_counter()
            tick = time.perf_counter()
    finally:
        stop.restore()
        collector.shutdown()
        if req.backend == "ray" and not req.ray_address:  # the local Ray this run started
            import ray

            ray.shutdown()
    return run.save()


class RunWriter:
    """What a run writes: the networks, the curve and the sidecar, each file replaced whole."""

    def __init__(self, req: TrainRequest, actor, critic, value_norm, spec, init, n_robots: int, t0: float):
        self.req, self.actor, self.critic, self.value_norm, self.spec = req, actor, critic, value_norm, spec
        self.init, self.n_robots, self.t0 = init, n_robots, t0
        self.commit = git_commit(Path(__file__).parent)
        """The code the run started with (the checkout may change while it runs)."""
        self.rows: list[dict] = []
        self.agent_steps = 0

    def save(self) -> dict:
        """Write ``policy.pt``, ``critic.pt``, ``curve.csv``, ``curve.png`` and ``run.json``; returns the sidecar."""
        import importlib.metadata as md
        import os

        from parcover_env.harness.marl_scan_head import actor_head

        req, out = self.req, self.req.out
        out.mkdir(parents=True, exist_ok=True)
        for name, write in ((POLICY_FILE, lambda p: save_policy(self.actor, p)),
                            (CRITIC_FILE, lambda p: save_critic(p, self.critic, self.value_norm, self.spec)),
                            (CURVE_FILE, lambda p: write_csv(p, self.rows))):
            tmp = out / f".{name}.tmp"
            write(tmp)
            if tmp.exists():  # write_csv writes nothing before the first episode ends
                os.replace(tmp, out / name)
        plot_curve(out)  # curve.png: KPOI fraction of the training episodes against agent-steps and wall time
        sidecar = {
            "algo": req.algo, "library": {"name": "torchrl", "version": md.version("torchrl")},
            "backend": req.backend, "ray_address": req.ray_address, "scenario": req.scenario, "init": self.init,
            "agent_steps": self.agent_steps, "wall_time": round(time.perf_counter() - self.t0, 3), "seed": req.seed,
            "command": req.command, "commit": self.commit, "config_file": req.config_path,
            "config": asdict(req.config), "n_robots": self.n_robots, "episodes": len(self.rows),
            "policy": f"torchrl:{out / POLICY_FILE}", "env_overrides": req.config.env, "curve": CURVE_FILE,
            "scan_head": actor_head(self.actor),
        }
        tmp = out / f".{SIDECAR_FILE}.tmp"
        tmp.write_text(json.dumps(sidecar, indent=2) + "\n")
        os.replace(tmp, out / SIDECAR_FILE)
        return sidecar
