"""Training throughput (collection + PPO update) in agent-steps/s: ``parcover train`` beside TorchRL MAPPO on VMAS.

Issue 40's target: on the generated pool, realistic preset, scans on, the whole loop reaches
>= 10k agent-steps/s and >= 1x TorchRL's MAPPO on VMAS ``navigation`` (same worlds and network size).
One run, one table, every row with the same worlds, hidden sizes, frames per batch, epochs and minibatch:

* ``pool scan``: ``parcover train``'s own loop (:func:`~parcover_env.harness.marl.train`, timed through its
  ``on_batch`` hook) with ``--config`` (MAPPO, realistic preset, scan service on, attention critic) and the
  ``bernoulli`` scan head, on ``generated:0-499``, collecting from the batched env (``collector_env:
  batched``, :class:`~parcover_env.train.batched_env.BatchedRobotsEnv`) with every world on its own maps
  (``worlds_per_map: 1``, one stepper call per world);
* ``pool scan grouped``: the same with all worlds on one drawn map at a time (``worlds_per_map`` = worlds:
  one stepper call for all; a world whose episode ends early idles until its group's last ends);
* ``pool scan serial``: the same through TorchRL's ``SerialEnv`` of one PettingZoo env per world
  (``collector_env: serial``, how ``parcover train`` collected before);
* ``pool no scan`` (``grouped``, ``serial``): the three with ``observation.scan.enabled: false``;
* ``vmas navigation``: TorchRL's MAPPO recipe, written here: ``VmasEnv`` (``worlds`` vectorized envs,
  ``--vmas-agents`` agents), ``MultiAgentMLP`` actor (TanhNormal) and centralised critic, ``ClipPPOLoss``
  with GAE, Adam, the same clip, coefficients, learning rate and gradient-norm clip.

Each row trains ``--repeats + 1`` batches; the first is warm-up (``parcover train`` only fits its input scale
on it) and each column is the median over the others. collect: the collector's batch; update: GAE, buffer and
``epochs x frames / minibatch`` Adam steps; loop: agent-steps / (collect + update seconds). Agent-steps exclude
a map pool's padding robots and idle worlds (idle: the share of the timed world-steps a world idled, waiting
for its group's next map); worlds/s: world-steps (frames) collected per second, which the maps' team sizes do
not change. One torch thread (as ``parcover train`` sets). The collection split of the scan
row's warm-up batch is sampled by pyinstrument (the ``bench`` extra), printed when it is importable.
The collectors seed their worlds differently, so each row runs other maps; with scans the localizer's cost
depends on the map and on how often the fresh actor scans: compare collectors on the no-scan rows.

    PYTHONPATH=. nice -n 10 .venv/bin/python benchmarks/train_throughput.py
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import dataclasses
import io
import os
import statistics
import tempfile
import time
from pathlib import Path

TARGET = 10_000.0
"""Issue 40: whole-loop agent-steps/s on the generated pool with scans."""
SPLIT = (("localizer", "parcover_env/localization/"),
         ("policy", "torch/nn/modules/", "torch/distributions/", "marl_scan_head", "torchrl_policy"),
         ("adapter", "parcover_env/harness/marl_env", "parcover_env/harness/map_pool", "parcover_env/train/"),
         ("env", "parcover_env/"), ("TorchRL", "torchrl/", "tensordict/"))
"""Collection split: a sample with a frame of the sonar localizer is the localizer's (with the ray casts and
kernels it calls); any other goes to the group of its innermost frame whose path holds a marker (groups tried
in this order per frame): the actor's forward pass and sampling, the array->tensor adapter
(:mod:`parcover_env.train`'s batched env, or :class:`~parcover_env.harness.marl_env.RobotsEnv` and the map
pool's padding), the rest of the env, and TorchRL
(collector, ``SerialEnv``, tensordicts); numba kernels count for the Python function that calls them."""


ROWS = {"scan": ("pool scan", True, "batched", False), "scan-grouped": ("pool scan grouped", True, "batched", True),
        "scan-serial": ("pool scan serial", True, "serial", False),
        "noscan": ("pool no scan", False, "batched", False),
        "noscan-grouped": ("pool no scan grouped", False, "batched", True),
        "noscan-serial": ("pool no scan serial", False, "serial", False)}
"""``--rows`` name: (printed name, scan service on, ``collector_env``, all worlds on one map at a time)."""


def collection_split(frame_records) -> dict[str, float]:
    """Fractions of the collection samples of a pyinstrument session's ``frame_records`` (stacks of
    ``function\\0path\\0line`` identifiers) per group of :data:`SPLIT`; collection samples are those
    under a TorchRL collector's ``iterator``/``rollout``."""
    seconds = dict.fromkeys([g[0] for g in SPLIT], 0.0)
    for stack, dt in frame_records:
        frames = [(f[0], f[1].replace("\\", "/")) for f in (ident.split("\x00") for ident in stack) if len(f) > 1]
        if not any(fn in ("iterator", "rollout") and "torchrl/collectors/" in path for fn, path in frames):
            continue
        inner = SPLIT[1:] if not any(SPLIT[0][1] in path for _, path in frames) else SPLIT[:1]
        groups = (next((g[0] for g in inner if any(m in path for m in g[1:])), None) for _, path in reversed(frames))
        seconds[next(g for g in groups if g is not None)] += dt  # the collector's frame is TorchRL's
    total = sum(seconds.values())
    return {k: v / total for k, v in seconds.items()} if total else {}


def parcover_row(scenario: str, cfg, config_path: str, repeats: int, profile: bool) -> dict:
    """Time ``repeats + 1`` batches of :func:`~parcover_env.harness.marl.train` (MAPPO); per-batch rows."""
    from parcover_env.harness.marl import GROUP, TrainRequest, train

    rows, profiler = [], None
    if profile:
        from pyinstrument import Profiler

        profiler = Profiler(interval=0.002)

    def on_batch(batch, collect_s: float, update_s: float) -> bool:
        if profiler is not None and profiler.is_running:
            profiler.stop()
        action = batch.get((GROUP, "action"))  # [..., robots, components]
        real = 1.0 - batch.get((GROUP, "info", "pad")).reshape(action.shape[:-1])  # the map's robots
        scans = float(((action[..., 2] > 0) * real).sum() / real.sum()) if action.shape[-1] == 3 else 0.0
        idle = float((real.amax(-1) == 0).float().mean())  # world-steps without a real robot
        rows.append({"steps": float(real.sum()), "collect_s": collect_s, "update_s": update_s, "scans": scans,
                     "idle": idle, "frames": float(batch.numel())})
        return len(rows) > repeats

    steps = (repeats + 1) * cfg.frames_per_batch * cfg.max_robots  # an upper bound: on_batch stops the run
    with tempfile.TemporaryDirectory() as out, contextlib.redirect_stdout(io.StringIO()):
        req = TrainRequest("mappo", scenario, steps, Path(out), cfg, config_path, seed=0)
        if profiler is not None:
            profiler.start()
        train(req, on_batch=on_batch)
    split = collection_split(profiler.last_session.frame_records) if profiler is not None else {}
    return {"batches": rows[1:], "split": split, "scans": statistics.median(r["scans"] for r in rows),
            "idle": statistics.mean(r["idle"] for r in rows[1:])}


def vmas_row(cfg, worlds: int, agents: int, repeats: int, max_steps: int = 100) -> dict:
    """TorchRL's MAPPO recipe on VMAS ``navigation``, ``repeats + 1`` batches of ``cfg.frames_per_batch``."""
    import torch
    from tensordict.nn import NormalParamExtractor, TensorDictModule
    from torch import nn
    from torchrl.collectors import Collector
    from torchrl.data import LazyTensorStorage, ReplayBuffer
    from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement
    from torchrl.envs import RewardSum, TransformedEnv
    from torchrl.envs.libs.vmas import VmasEnv
    from torchrl.modules import MultiAgentMLP, ProbabilisticActor, TanhNormal
    from torchrl.objectives import ClipPPOLoss, ValueEstimators

    torch.manual_seed(0)
    env = VmasEnv(scenario="navigation", num_envs=worlds, continuous_actions=True, max_steps=max_steps,
                  device="cpu", n_agents=agents, seed=0)
    env = TransformedEnv(env, RewardSum(in_keys=[env.reward_key], out_keys=[("agents", "episode_reward")]))
    obs_dim = env.observation_spec["agents", "observation"].shape[-1]
    act_spec = env.full_action_spec_unbatched[env.action_key]
    depth, cells = len(cfg.hidden), list(cfg.hidden)
    actor_mlp = MultiAgentMLP(obs_dim, 2 * act_spec.shape[-1], agents, centralized=False, share_params=True,
                              depth=depth, num_cells=cells, activation_class=nn.Tanh)
    actor = ProbabilisticActor(
        TensorDictModule(nn.Sequential(actor_mlp, NormalParamExtractor()), in_keys=[("agents", "observation")],
                         out_keys=[("agents", "loc"), ("agents", "scale")]),
        spec=act_spec, in_keys=[("agents", "loc"), ("agents", "scale")], out_keys=[env.action_key],
        distribution_class=TanhNormal, return_log_prob=True,
        distribution_kwargs={"low": act_spec.space.low, "high": act_spec.space.high})
    critic = TensorDictModule(MultiAgentMLP(obs_dim, 1, agents, centralized=True, share_params=True, depth=depth,
                                            num_cells=cells, activation_class=nn.Tanh),
                              in_keys=[("agents", "observation")], out_keys=[("agents", "state_value")])
    loss = ClipPPOLoss(actor_network=actor, critic_network=critic, clip_epsilon=cfg.clip_epsilon,
                       entropy_bonus=cfg.entropy_coeff > 0, entropy_coeff=cfg.entropy_coeff,
                       critic_coeff=cfg.critic_coeff, normalize_advantage=False)  # the recipe's
    loss.set_keys(reward=env.reward_key, action=env.action_key, value=("agents", "state_value"),
                  done=("agents", "done"), terminated=("agents", "terminated"))
    loss.make_value_estimator(ValueEstimators.GAE, gamma=cfg.gamma, lmbda=cfg.gae_lambda)
    optim = torch.optim.Adam(loss.parameters(), lr=cfg.learning_rate)
    frames = cfg.frames_per_batch
    buffer = ReplayBuffer(storage=LazyTensorStorage(frames), sampler=SamplerWithoutReplacement(),
                          batch_size=cfg.minibatch_size)
    collector = Collector(env, actor, frames_per_batch=frames, total_frames=(repeats + 1) * frames,
                          auto_register_policy_transforms=False)
    rows, tick = [], time.perf_counter()
    for batch in collector:
        collect_s, start = time.perf_counter() - tick, time.perf_counter()
        shape = batch.get_item_shape(("next", env.reward_key))
        for key in ("done", "terminated"):  # the group's flags, as the recipe sets them
            batch.set(("next", "agents", key), batch.get(("next", key)).unsqueeze(-1).expand(shape))
        with torch.no_grad():
            loss.value_estimator(batch, params=loss.critic_network_params,
                                 target_params=loss.target_critic_network_params)
        buffer.extend(batch.reshape(-1))
        for _ in range(cfg.epochs * (frames // cfg.minibatch_size)):
            parts = loss(buffer.sample())
            total = parts["loss_objective"] + parts["loss_critic"] + parts.get("loss_entropy", 0.0)
            optim.zero_grad()
            total.backward()
            torch.nn.utils.clip_grad_norm_(loss.parameters(), cfg.max_grad_norm)
            optim.step()
        collector.update_policy_weights_()
        rows.append({"steps": float(batch.numel() * agents), "frames": float(batch.numel()), "collect_s": collect_s,
                     "update_s": time.perf_counter() - start})
        tick = time.perf_counter()
    collector.shutdown()
    return {"batches": rows[1:]}


def medians(batches: list[dict]) -> dict[str, float]:
    """Median agent-steps/s of collection, update and the loop (collect + update) over ``batches``, and the
    median world-steps/s of collection (``worlds``: frames / collect seconds, whatever the team sizes)."""
    med = statistics.median
    return {"worlds": med(b["frames"] / b["collect_s"] for b in batches),
            "collect": med(b["steps"] / b["collect_s"] for b in batches),
            "update": med(b["steps"] / b["update_s"] for b in batches),
            "loop": med(b["steps"] / (b["collect_s"] + b["update_s"]) for b in batches)}


def main(argv: list[str] | None = None) -> int:
    import torch

    from parcover_env.harness.marl_config import load_marl_config

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", nargs="?", default="generated:0-499")
    p.add_argument("--config", default="configs/train/mappo_generated_scan_sigma.yaml")
    p.add_argument("--frames", type=int, default=1024,
                   help="frames (env steps, all worlds) per batch, every row (the config's: 4096, ~4x longer)")
    p.add_argument("--repeats", type=int, default=3, help="timed batches per row, after one warm-up batch")
    p.add_argument("--vmas-agents", type=int, default=None, help="VMAS agents (default: the config's max_robots)")
    p.add_argument("--rows", nargs="+", default=list(ROWS) + ["vmas"], choices=list(ROWS) + ["vmas"])
    p.add_argument("--no-profile", dest="profile", action="store_false", help="skip the collection split")
    a = p.parse_args(argv)
    base = load_marl_config("mappo", a.config)
    base = dataclasses.replace(base, frames_per_batch=a.frames, minibatch_size=min(base.minibatch_size, a.frames),
                               scan_head="bernoulli", checkpoint_every=0, wall_time=0)
    noscan_env = copy.deepcopy(base.env)
    noscan_env.setdefault("observation", {}).setdefault("scan", {})["enabled"] = False
    agents = a.vmas_agents or base.max_robots
    torch.set_num_threads(1)
    profile, why = a.profile, "--no-profile"
    if profile:
        try:
            import pyinstrument  # noqa: F401
        except ImportError:
            profile, why = False, "pyinstrument is not installed (pip install 'parcover_env[bench]')"
    results, notes = {}, []
    for row in a.rows:
        if row == "vmas":
            try:
                import vmas  # noqa: F401
            except ImportError:
                notes.append("vmas navigation: SKIPPED, vmas is not installed (pip install 'parcover_env[bench]')")
                continue
            results["vmas navigation"] = vmas_row(base, base.worlds, agents, a.repeats)
        else:
            name, scan, collector, grouped = ROWS[row]
            cfg = dataclasses.replace(base, env=base.env if scan else noscan_env, collector_env=collector,
                                      worlds_per_map=base.worlds if grouped else 1)
            results[name] = parcover_row(a.scenario, cfg, a.config, a.repeats, profile and row == "scan")
    load = os.getloadavg()[0]
    print(f"{a.scenario} ({a.config}, realistic, MAPPO, bernoulli scan head) vs VMAS navigation ({agents} agents): "
          f"{base.worlds} worlds, hidden {list(base.hidden)}, {a.frames} frames/batch, {base.epochs} epochs x "
          f"minibatch {base.minibatch_size}; medians of {a.repeats} batches after 1 warm-up; 1 torch thread; "
          f"load average {load:.1f} on {os.cpu_count()} cores (shared machine: figures are lower bounds)")
    vmas_loop = medians(results["vmas navigation"]["batches"])["loop"] if "vmas navigation" in results else None
    head = (f"{'row':<20} {'collect/s':>10} {'update/s':>10} {'loop/s':>10} {'vs VMAS':>8} {'idle':>5} "
            f"{'worlds/s':>9}  "
            f"target (loop >= {TARGET:.0f}/s; >= 1x VMAS)")
    print(head + "\n" + "-" * len(head))
    for name, res in results.items():
        m = medians(res["batches"])
        ratio = f"{m['loop'] / vmas_loop:.2f}x" if vmas_loop else "n/a"
        idle = f"{res['idle']:.0%}" if "idle" in res else "-"
        target = ""
        if name.startswith("pool scan"):
            ok_vmas = "n/a" if vmas_loop is None else ("met" if m["loop"] >= vmas_loop else "NOT met")
            target = f"{'met' if m['loop'] >= TARGET else 'NOT met'} ({m['loop'] / TARGET:.0%}); VMAS: {ok_vmas}"
        print(f"{name:<20} {m['collect']:>10.0f} {m['update']:>10.0f} {m['loop']:>10.0f} {ratio:>8} {idle:>5} "
              f"{m['worlds']:>9.0f}  "
              f"{target}")
    for note in notes:
        print(note)
    if "pool scan" in results:
        res = results["pool scan"]
        split = ", ".join(f"{k} {v:.0%}" for k, v in res["split"].items()) if res["split"] else (
            "not sampled: " + why)
        print(f"pool scan: scan requested on {res['scans']:.0%} of real robot-steps (fresh actor); "
              f"collection split of its warm-up batch: {split}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
