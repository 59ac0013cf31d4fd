"""``parcover train bc``: behaviour cloning (and DAgger) of the scripted expert into the TorchRL actor.

The network fitted is the one ``parcover train ippo|mappo`` builds from the same config
(:func:`~parcover_env.harness.marl.build_actor`: the same observation box scaling, hidden widths and
head), so its ``policy.pt`` evaluates as ``torchrl:DIR/policy.pt`` and starts a PPO run with
``parcover train ippo|mappo ... --init DIR``.

Data: :func:`~parcover_env.harness.datasets.record_episodes` under the config's preset and ``env``
overrides, one episode per seed ``seed, seed + 1, ...`` (each below the first evaluation seed,
:data:`~parcover_env.harness.map_pool.FIRST_EVAL_SEED`); on a map pool ``generated:A-B`` (evaluation
maps refused) episode ``i`` runs on the pool's map ``A + i mod (B - A + 1)``. Every robot's
``(observation, expert action)`` pair is one sample.

Loss (:func:`imitation_loss`), averaged over the samples:

- drive ``(v, omega)`` (every component for the ``continuous`` head): the squared error of the
  TanhNormal's deterministic action ``tanh(loc)`` (what ``torchrl:`` runs) to the expert's, summed over
  the components. The TanhNormal's scale is not fitted: its negative log-likelihood on the
  deterministic expert drives the scales of the well-fitted samples to the floor, whose gradients
  then swamp the others' (on the 8-sample set of ``tests/train/test_imitation.py``, 64 hidden units,
  400 Adam steps at 0.01: largest error of ``tanh(loc)`` 1.22 under the log-likelihood, 0.04 under
  the squared error);
- scan (the ``bernoulli`` head, with the env's scan service): a discrete label, the Bernoulli
  negative log-likelihood of ``scan > 0``, ``softplus(-l)`` for a scan and ``softplus(l)`` otherwise.

DAgger (Ross et al. 2011, ``dagger_rounds`` R > 0): after the behaviour-cloning fit, each round
records ``episodes`` more episodes on new seeds in which the fitted actor drives (deterministic, as
``torchrl:``) and the expert labels every step, adds them to the data and fits again (continuing
from the current weights). The sidecar ``run.json`` states that the policy is an imitation of the
scripted expert (``made_by``), the data and the fit. torch and torchrl are imported inside the functions.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from parcover_env.errors import ArgumentError
from parcover_env.harness.map_pool import FIRST_EVAL_SEED, is_pool, parse_pool
from parcover_env.harness.marl_config import MarlConfig
from parcover_env.policies.torchrl_policy import POLICY_FILE, SIDECAR_FILE

__all__ = ["ImitationRequest", "Demonstrations", "episode_maps", "record", "imitation_loss", "fit", "imitate"]

LABELLER = "expert"


@dataclass(frozen=True)
class ImitationRequest:
    """One ``parcover train bc`` run."""

    scenario: str
    steps: int
    """Gradient steps of each fit (minibatches of ``config.minibatch_size`` samples, Adam at
    ``config.learning_rate``)."""
    out: Path
    config: MarlConfig
    """The PPO config whose actor is fitted (network, preset, env overrides, scan head)."""
    config_path: str
    episodes: int = 10
    """Expert episodes recorded before the first fit, and again in each DAgger round."""
    dagger_rounds: int = 0
    seed: int = 0
    """First episode seed; also torch's seed (initial weights, minibatches)."""
    command: str = ""
    max_steps: int | None = None
    """Step limit of a recorded episode (the env's ``episode.max_steps``); None: the scenario's (the CLI's)."""

    def check(self) -> ImitationRequest:
        """Self, or one ArgumentError naming the first bad argument."""
        if self.episodes < 1:
            raise ArgumentError(f"--episodes must be >= 1, got {self.episodes}")
        if self.dagger_rounds < 0:
            raise ArgumentError(f"--dagger-rounds must be >= 0, got {self.dagger_rounds}")
        if self.steps < 1:
            raise ArgumentError(f"--steps must be >= 1, got {self.steps}")
        last = self.seed + self.episodes * (self.dagger_rounds + 1) - 1
        if last >= FIRST_EVAL_SEED:
            raise ArgumentError(f"--seed {self.seed} with {self.episodes} episodes x {self.dagger_rounds + 1} "
                                f"round(s) records seeds up to {last}; seeds >= {FIRST_EVAL_SEED} are evaluation "
                                "seeds, not for training")
        if is_pool(self.scenario):
            parse_pool(self.scenario)  # ConfigError for a malformed pool or one reaching the evaluation maps
        return self


@dataclass(frozen=True)
class Demonstrations:
    """Aggregated samples: ``observations [N, D]`` (float32) and the labeller's ``actions [N, A]``."""

    observations: np.ndarray
    actions: np.ndarray

    @classmethod
    def from_episodes(cls, episodes) -> Demonstrations:
        """Every step of every :class:`~parcover_env.harness.datasets.AgentEpisode` (the observation
        the action was taken in, not the last one)."""
        obs = [np.asarray(e["observations"][:-1], np.float32) for e in episodes]
        act = [np.asarray(e["actions"], np.float32) for e in episodes]
        return cls(np.concatenate(obs), np.concatenate(act))

    def __add__(self, other: Demonstrations) -> Demonstrations:
        return Demonstrations(np.concatenate([self.observations, other.observations]),
                              np.concatenate([self.actions, other.actions]))

    def __len__(self) -> int:
        return len(self.observations)


def episode_maps(scenario: str, first: int, count: int) -> list[str]:
    """The scenario of episodes ``first .. first + count - 1``: ``scenario`` itself, or on a map pool
    its maps in turn (``generated:SEED``, episode ``i`` on the pool's ``i mod size``-th map)."""
    if not is_pool(scenario):
        return [scenario] * count
    seeds = parse_pool(scenario)
    return [f"generated:{seeds[i % len(seeds)]}" for i in range(first, first + count)]


def _distribution(actor, obs):
    from tensordict import TensorDict

    from parcover_env.harness.marl_loss import GROUP

    td = TensorDict({GROUP: TensorDict({"observation": obs}, batch_size=obs.shape[:1])}, batch_size=obs.shape[:1])
    return actor.get_dist(td)


def imitation_loss(actor, obs, actions) -> dict:
    """``{"loss", "drive", "scan"}`` of ``actor`` (a :func:`~parcover_env.harness.marl.build_actor`) on
    observations ``obs [N, D]`` and labels ``actions [N, A]`` (torch tensors): ``drive`` the mean over
    the samples of the squared error of the TanhNormal's deterministic action ``tanh(loc)``, summed over
    its components; ``scan`` the mean Bernoulli negative log-likelihood of ``scan > 0`` (0 for the
    ``continuous`` head, whose TanhNormal covers every component); ``loss`` their sum."""
    import torch

    from parcover_env.harness.marl_scan_head import TanhNormalScan

    dist = _distribution(actor, obs)
    if isinstance(dist, TanhNormalScan):
        mode, labels = torch.tanh(dist.drive.loc), actions[..., :-1]
        bit = (actions[..., -1] > 0).to(dist.scan.logits.dtype)
        scan = -dist.scan.log_prob(bit).mean()
    else:
        mode, labels, scan = torch.tanh(dist.loc), actions, torch.zeros(())
    drive = ((mode - labels) ** 2).sum(-1).mean()
    return {"loss": drive + scan, "drive": drive, "scan": scan}


def fit(actor, data: Demonstrations, steps: int, learning_rate: float, batch_size: int, generator,
        max_grad_norm: float | None = None, optimizer=None) -> tuple[list[float], object]:
    """``steps`` Adam steps on :func:`imitation_loss` over minibatches of ``batch_size`` samples drawn
    with replacement by ``generator`` (a torch Generator); gradients clipped to ``max_grad_norm`` if
    given. Returns the minibatch losses and the optimizer (pass it back to continue)."""
    import torch

    from parcover_env.harness.marl import policy_net

    net = policy_net(actor)
    optimizer = optimizer or torch.optim.Adam(net.parameters(), lr=learning_rate)
    obs, act = torch.as_tensor(data.observations), torch.as_tensor(data.actions)
    losses = []
    for _ in range(steps):
        idx = torch.randint(len(obs), (min(batch_size, len(obs)),), generator=generator)
        loss = imitation_loss(actor, obs[idx], act[idx])["loss"]
        optimizer.zero_grad()
        loss.backward()
        if max_grad_norm:
            torch.nn.utils.clip_grad_norm_(net.parameters(), max_grad_norm)
        optimizer.step()
        losses.append(float(loss.detach()))
    return losses, optimizer


def record(req: ImitationRequest, first: int, driver: str | None) -> Demonstrations:
    """Episodes ``first .. first + episodes - 1`` of ``req`` (seeds ``seed + i``, maps of
    :func:`episode_maps`), labelled by the expert and driven by ``driver`` (a policy spec; None: the expert)."""
    from parcover_env.harness.datasets import record_episodes

    cfg, eps = req.config, []
    for i, scenario in enumerate(episode_maps(req.scenario, first, req.episodes), start=first):
        eps += record_episodes(scenario, 1, seed=req.seed + i, policy=LABELLER, preset=cfg.preset,
                               driver=driver, overrides=cfg.env or None, max_steps=req.max_steps)
    return Demonstrations.from_episodes(eps)


def imitate(req: ImitationRequest, log=print) -> dict:
    """Record, fit (and DAgger rounds), then write ``policy.pt`` and ``run.json`` into ``req.out``;
    returns the sidecar. ``log`` gets one line per round."""
    import torch

    from parcover_env.harness.marl import EnvMaker, build_actor, policy_net, run_scan_head
    from parcover_env.harness.marl_scale import fit_scale

    req.check()
    torch.set_num_threads(1)
    torch.manual_seed(req.seed)
    cfg, t0 = req.config, time.perf_counter()
    base = EnvMaker(req.scenario, cfg.preset, cfg.episode_steps, overrides=cfg.env, max_robots=cfg.max_robots,
                    state=False).parallel()  # the observation box PPO's actor scales by (a pool's: POOL_BOX)
    obs_space, act_dim = base.observation_space(base.possible_agents[0]), base.action_space("robot_0").shape[0]
    actor = build_actor(obs_space.low, obs_space.high, act_dim, cfg.hidden, run_scan_head(cfg, act_dim))
    generator = torch.Generator().manual_seed(req.seed)
    driver = f"torchrl:{req.out / POLICY_FILE}"
    data, optimizer, rounds = None, None, []
    for r in range(req.dagger_rounds + 1):
        new = record(req, r * req.episodes, driver if r else None)
        data = new if data is None else data + new
        if r == 0 and cfg.obs_scale == "rollout":  # as PPO's first batch does, from the expert's observations
            with torch.no_grad():
                fit_scale(policy_net(actor)[0], torch.as_tensor(data.observations))
        losses, optimizer = fit(actor, data, req.steps, cfg.learning_rate, cfg.minibatch_size, generator,
                                cfg.max_grad_norm, optimizer)
        final = float(np.mean(losses[-min(50, len(losses)):]))
        rounds.append({"round": r, "driver": "expert" if r == 0 else "learner", "new_samples": len(new),
                       "samples": len(data), "final_loss": round(final, 6)})
        log(f"round {r} ({rounds[-1]['driver']} drove): {len(new)} new samples, {len(data)} in all; "
            f"{req.steps} gradient steps, loss {final:.4f} (mean of the last {min(50, len(losses))})")
        sidecar = _save(req, actor, rounds, t0)
    return sidecar


def _save(req: ImitationRequest, actor, rounds: list[dict], t0: float) -> dict:
    """Write ``policy.pt`` (as PPO's :func:`~parcover_env.harness.marl.save_policy`) and ``run.json``;
    returns the sidecar as the file reads back."""
    import importlib.metadata as md

    from parcover_env.harness.marl import save_policy
    from parcover_env.harness.marl_scan_head import actor_head
    from parcover_env.harness.training import git_commit

    out = req.out
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / f".{POLICY_FILE}.tmp"
    save_policy(actor, tmp)
    os.replace(tmp, out / POLICY_FILE)
    algo = "dagger" if len(rounds) > 1 else "bc"
    how = (f"DAgger, {len(rounds) - 1} round(s) after behaviour cloning" if algo == "dagger"
           else "behaviour cloning")
    sidecar = {
        "algo": algo,
        "made_by": f"imitation: {how} of the scripted expert ({LABELLER}) into the TorchRL actor; "
                   "not reinforcement learning",
        "library": {"name": "torchrl", "version": md.version("torchrl")},
        "scenario": req.scenario, "init": None, "seed": req.seed, "command": req.command,
        "commit": git_commit(Path(__file__).parent), "config_file": req.config_path, "config": asdict(req.config),
        "env_overrides": req.config.env,
        "data": {"scenario": req.scenario, "labeller": LABELLER, "episodes": req.episodes * len(rounds),
                 "episodes_per_round": req.episodes, "rounds": len(rounds) - 1,
                 "seeds": [req.seed, req.seed + req.episodes * len(rounds) - 1],
                 "samples": rounds[-1]["samples"], "preset": req.config.preset},
        "fit": {"steps_per_round": req.steps, "learning_rate": req.config.learning_rate,
                "batch_size": req.config.minibatch_size, "max_grad_norm": req.config.max_grad_norm,
                "drive_loss": "squared error of tanh(loc) to the expert action (the scale is not fitted)",
                "scan_loss": "Bernoulli negative log-likelihood of scan > 0" if actor_head(actor) == "bernoulli"
                else None, "rounds": rounds},
        "agent_steps": 0, "episodes": req.episodes * len(rounds),
        "wall_time": round(time.perf_counter() - t0, 3),
        "policy": f"torchrl:{out / POLICY_FILE}", "scan_head": actor_head(actor),
    }
    text = json.dumps(sidecar, indent=2) + "\n"
    tmp = out / f".{SIDECAR_FILE}.tmp"
    tmp.write_text(text)
    os.replace(tmp, out / SIDECAR_FILE)
    return json.loads(text)  # as the file reads back (lists, not tuples)
