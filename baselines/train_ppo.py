"""Train PPO with parameter sharing on parcover scenarios (one policy for every robot).

    python baselines/train_ppo.py --scenario office --total-timesteps 600000 --out runs/ppo_office
    python baselines/train_ppo.py --curriculum docs/lab/train_configs/generated_to_tree.yaml --out runs/ppo_tree
    python baselines/train_ppo.py --scenario tree --bc-episodes 6 --out runs/bcppo_tree   # BC-initialized
    # BC from Minari datasets (parcover collect), PPO held near it, best network by validation
    python baselines/train_ppo.py --scenario generated:RANDOM --map-seed0 200 \
        --bc-datasets 'parcover/generated-*-expert-v0' --drop-obs x,y,cos_theta,sin_theta \
        --learning-rate 3e-5 --n-epochs 3 --target-kl 0.02 --bc-coef 0.5 \
        --eval-scenarios generated:500,generated:501,generated:502 --eval-episodes 1 --out runs/ppo_generated

Writes into ``OUT/``: ``model.zip`` + ``vecnormalize.pkl`` (read by
``parcover_env.policies.learned.PPOPolicy``, i.e. ``--policy ppo:OUT``), ``model.json`` (sidecar:
exact command, git commit, seeds, steps, wall time, preset, versions), ``curve.csv`` / ``curve.png``
(training episodes against agent-steps and wall time), ``eval.csv`` (periodic evaluation on
validation seeds, disjoint from the training seeds and from the benchmark's seeds >= 1000),
``checkpoints/step_<N>.zip`` (+ stats) every ``--checkpoint-freq`` agent-steps, and TensorBoard
event files under ``OUT/tb`` when the ``tensorboard`` package is installed.

Curriculum: ``--curriculum FILE`` (YAML, e.g. ``docs/lab/train_configs/generated.yaml``) lists stages
``{scenario, steps, n_envs, wall_time}``; the policy, its optimizer and the observation/return
normalization carry over from stage to stage (the VecEnv is rebuilt, so team sizes may change).
``scenario: generated:RANDOM`` gives each ParallelEnv of the stage its own procedural map
(``generated:<map_seed0 + k>``), ``generated:A,B,C`` cycles through the listed maps.

BC initialization (``--bc-episodes N``, or ``--bc-datasets IDS`` to read the demonstrations from
Minari datasets written by ``parcover collect``): records N expert missions (seeds ``bc_seed0 ..``) on the
first stage's scenario, sets the observation/return normalization from them, regresses the actor's
mean action onto the expert's and the critic onto the demonstrations' discounted returns, saves that
network as ``OUT/bc_init/`` (evaluable as a policy by itself), then runs PPO from it.
Keeping the PPO phase from wrecking it: ``--bc-coef`` adds a BC regularizer (Adam steps toward the
expert's actions on the demonstrations after every rollout), ``--target-kl`` / ``--clip-range`` /
small ``--learning-rate`` bound each update, and with ``--eval-freq`` the starting network and every
periodic evaluation compete for ``OUT/best/`` (``--keep-best``): ship that one, not the last.

Hardware: ``--device auto`` uses CUDA when torch sees a GPU. With these small MLPs (2 x 128) the
simulation, not the network, is the bottleneck: a GPU mostly pays off with far larger batches
(many more envs); a Ray cluster would run the rollouts (``--multiprocess`` workers, one ParallelEnv
each, here processes on this machine) on many cores, which is what would shorten training here.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path


@dataclass
class Args:
    scenario: str = "office"
    """Scenario name or YAML path; ``generated:RANDOM`` = a different procedural map per env.
    Ignored when ``curriculum`` is given."""
    curriculum: str = ""
    """YAML file with ``stages: [{scenario, steps, n_envs?, wall_time?}]``
    (e.g. docs/lab/train_configs/generated.yaml)."""
    preset: str = "realistic"
    """``realistic`` (default error models) or ``ideal`` (every error model off)."""
    seed: int = 0
    """Seeds torch, the PPO sampler and the training episodes (ParallelEnv k resets with seed + k)."""
    map_seed0: int = 0
    """First procedural map of ``generated:RANDOM`` stages (stage s, env k: map_seed0 + 100 s + k)."""
    total_timesteps: int = 1_000_000
    """Agent-steps (one per robot per env step) without a curriculum."""
    n_envs: int = 4
    """ParallelEnvs; slots = n_envs x n_robots."""
    multiprocess: bool = False
    """One worker process per ParallelEnv."""
    n_steps: int = 256
    """Rollout length per slot between updates."""
    batch_size: int = 1024
    n_epochs: int = 5
    learning_rate: float = 3e-4
    gamma: float = 0.995
    gae_lambda: float = 0.95
    ent_coef: float = 0.0
    log_std_init: float = 0.0
    net_arch: str = "128,128"
    drop_obs: str = ""
    """Comma-separated observation fields the networks do not see (e.g. ``x,y,cos_theta,sin_theta``:
    the world-frame pose, meaningless on unseen maps); see ``parcover_env.policies.sb3_features``."""
    max_steps: int = 0
    """Override episode.max_steps (0 = the scenario's)."""
    out: str = "runs/ppo"
    device: str = "auto"
    """torch device: ``auto`` (CUDA if available, else CPU), ``cpu``, ``cuda``."""
    threads: int = 1
    """torch CPU threads."""
    max_wall_time: float = 0.0
    """Stop training after this many seconds (0 = no limit); the model so far is saved."""
    eval_freq: int = 100_000
    """Evaluate every this many agent-steps (0 = never)."""
    eval_episodes: int = 2
    """Episodes per evaluation and scenario (seeds eval_seed0 ..)."""
    eval_seed0: int = 500
    """First validation seed: disjoint from training seeds (0 ..) and benchmark seeds (>= 1000)."""
    eval_scenarios: str = ""
    """Comma-separated validation scenarios (default: the current stage's; RANDOM -> generated:500..)."""
    checkpoint_freq: int = 200_000
    """Save ``checkpoints/step_<N>.zip`` every this many agent-steps (0 = never)."""
    resume: str = ""
    """A model.zip (or its directory) to continue from; its vecnormalize.pkl is loaded too."""
    init: str = ""
    """A model.zip to start from (its ``*vecnormalize.pkl`` beside it is loaded too): its networks,
    with this run's PPO settings (learning_rate, n_steps, batch_size, n_epochs, clip_range,
    target_kl, ent_coef, gamma) and steps counted from 0. Fine-tunes an imitation network with PPO,
    e.g. the DAgger network of ``baselines/dagger.py``."""
    vf_warmup: int = 0
    """Agent-steps at the start during which only the value network learns (the actor is frozen):
    a network from imitation has no trained critic, and PPO on its random values first un-learns
    the actor."""
    bc_episodes: int = 0
    """Expert missions for BC initialization (0 = PPO from scratch)."""
    bc_scenario: str = ""
    """Scenario of the demonstrations (default: the first stage's; ``generated:RANDOM`` = maps
    ``map_seed0 + 50 + k``, one mission each)."""
    bc_seed0: int = 2000
    """First seed of the BC demonstrations."""
    bc_epochs: int = 30
    bc_log_std: float = -1.0
    """Action log-std after BC initialization (small: act close to the cloned mean)."""
    bc_datasets: str = ""
    """Minari datasets of expert demonstrations (``parcover collect``) for BC initialization and the
    BC regularizer instead of recording missions: comma-separated ids, ``*`` wildcards allowed
    (``parcover/generated-*-expert-v0``); every episode of every dataset is used."""
    bc_dataset_root: str = "runs/datasets"
    """Root directory of the Minari datasets (MINARI_DATASETS_PATH)."""
    bc_coef: float = 0.0
    """Weight of the BC regularizer during PPO: after every rollout, ``bc_batches`` Adam steps on
    ``bc_coef`` x the mean squared error between the actor's mean action and the expert's on the
    demonstrations (0 = off). Keeps PPO near the cloned behaviour."""
    bc_batches: int = 8
    """Minibatches (of ``batch_size`` robot-steps) of the BC regularizer per rollout."""
    clip_range: float = 0.2
    """PPO ratio clipping."""
    target_kl: float = 0.0
    """Stop an update's epochs once the approximate KL to the rollout policy exceeds this (0 = off)."""
    keep_best: bool = True
    """With periodic evaluation: also evaluate the starting network (the BC init or the resumed
    model) and keep the network with the best validation score (mean KPOI fraction, then mean
    success; earlier wins ties) in ``OUT/best/`` (model.zip, vecnormalize.pkl, model.json)."""


_ARGV: list[str] = []
"""The arguments ``parse_args`` read (written into the sidecar's command)."""


def parse_args(argv=None) -> Args:
    """``Args`` from the command line (``--help`` lists every field with its docstring)."""
    import tyro

    _ARGV[:] = list(sys.argv[1:] if argv is None else argv)
    return tyro.cli(Args, args=argv, description=__doc__)


# ------------------------------------------------------------------------------ stages and envs
def load_stages(args: Args) -> list[dict]:
    """Curriculum stages ``[{scenario, steps, n_envs, wall_time}]`` (one stage without a curriculum)."""
    if not args.curriculum:
        return [{"scenario": args.scenario, "steps": args.total_timesteps, "n_envs": args.n_envs, "wall_time": 0.0}]
    import yaml

    spec = yaml.safe_load(Path(args.curriculum).read_text())
    stages = []
    for i, st in enumerate(spec.get("stages", [])):
        if "scenario" not in st or "steps" not in st:
            raise ValueError(f"{args.curriculum}: stage {i} needs 'scenario' and 'steps'")
        stages.append({"scenario": str(st["scenario"]), "steps": int(st["steps"]),
                       "n_envs": int(st.get("n_envs", args.n_envs)), "wall_time": float(st.get("wall_time", 0.0))})
    if not stages:
        raise ValueError(f"{args.curriculum}: no stages")
    return stages


def stage_scenarios(scenario: str, n_envs: int, map_seed: int) -> list[str]:
    """The scenario of each ParallelEnv of a stage."""
    if scenario == "generated:RANDOM":
        return [f"generated:{map_seed + k}" for k in range(n_envs)]
    if scenario.startswith("generated:") and "," in scenario:
        maps = scenario.removeprefix("generated:").split(",")
        return [f"generated:{maps[k % len(maps)]}" for k in range(n_envs)]
    return [scenario] * n_envs


def make_venv(args: Args, scenarios: list[str], seed: int):
    """The normalized SB3 VecEnv of a stage (:func:`parcover_env.harness.sb3_training.make_sb3_venv`)."""
    from parcover_env.harness.sb3_training import make_sb3_venv

    return make_sb3_venv(scenarios, seed, preset=args.preset, gamma=args.gamma, max_steps=args.max_steps,
                         multiprocess=args.multiprocess)


# ------------------------------------------------------------------------------ evaluation
def evaluate(model, venv, scenarios: list[str], args: Args) -> list[dict]:
    """Deterministic episodes on validation seeds; one row per episode."""
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.learned import ObsNormalizer, PPOPolicy

    actor = PPOPolicy.from_model(model, ObsNormalizer(venv.obs_rms.mean, venv.obs_rms.var, venv.clip_obs, venv.epsilon))
    rows = []
    for sc in scenarios:
        env = ParallelCoverageEnv(sc, preset=args.preset,
                                  overrides={"episode": {"max_steps": args.max_steps}} if args.max_steps else None)
        for k in range(args.eval_episodes):
            m = run_episode(env, actor, args.eval_seed0 + k)
            rows.append({"scenario": sc, "seed": args.eval_seed0 + k, "success": float(m["success"]),
                         "kpoi_fraction": m["kpois_visited"] / m["n_kpois"],
                         "makespan_ratio": m["makespan_ratio"], "collisions": m["collisions"]})
        env.close()
    return rows


def eval_scenarios_for(args: Args, stage: dict) -> list[str]:
    if args.eval_scenarios:
        return [s for s in args.eval_scenarios.split(",") if s]
    if stage["scenario"].startswith("generated:"):
        return [f"generated:{args.eval_seed0 + k}" for k in range(2)]
    return [stage["scenario"]]


# ------------------------------------------------------------------------------ BC initialization
def load_demos(args: Args, scenario: str) -> tuple[list[dict], dict]:
    """Expert demonstrations (one dict per robot-episode) and a description of where they came from:
    the Minari datasets ``args.bc_datasets`` if given, else ``args.bc_episodes`` missions recorded now
    on ``scenario`` (``generated:RANDOM``: maps ``map_seed0 + 50 + k``)."""
    from parcover_env.harness.datasets import dataset_ids, load_minari_many, record_episodes

    if args.bc_datasets:
        ids = dataset_ids(args.bc_datasets, args.bc_dataset_root)
        eps = load_minari_many(args.bc_datasets, args.bc_dataset_root)
        return eps, {"bc_datasets": ids, "bc_dataset_spec": args.bc_datasets}
    eps = []
    for k, sc in enumerate(stage_scenarios(scenario, args.bc_episodes, args.map_seed0 + 50)):
        eps += record_episodes(sc, 1, seed=args.bc_seed0 + k, max_steps=args.max_steps or None, preset=args.preset)
    return eps, {"bc_missions": args.bc_episodes, "bc_seeds": [args.bc_seed0, args.bc_seed0 + args.bc_episodes - 1]}


def bc_initialize(model, venv, args: Args, eps: list[dict]) -> dict:
    """Clone the expert into the PPO actor and the critic (:func:`parcover_env.harness.sb3_training.bc_initialize`)."""
    from parcover_env.harness.sb3_training import bc_initialize as clone

    return clone(model, venv, eps, gamma=args.gamma, seed=args.seed, epochs=args.bc_epochs, log_std=args.bc_log_std)


class BCRegularizer:
    """The BC term of the PPO phase: Adam steps on ``coef`` x MSE(actor mean, expert action) over
    random minibatches of the demonstrations, normalized with the env's current statistics."""

    def __init__(self, eps: list[dict], coef: float, batches: int, batch_size: int, seed: int):
        import numpy as np

        self.obs = np.concatenate([e["observations"][:-1] for e in eps]).astype(np.float32)
        self.act = np.clip(np.concatenate([e["actions"] for e in eps]), -1, 1).astype(np.float32)
        self.coef, self.batches, self.batch_size = coef, batches, batch_size
        self.rng = np.random.default_rng(seed)

    def step(self, model, venv) -> float:
        """Run the minibatches; returns the mean MSE before each step."""
        import torch

        if self.coef <= 0:  # off: no optimizer step at all (Adam's momentum would still move the weights)
            return float("nan")
        pol, total = model.policy, 0.0
        for _ in range(self.batches):
            idx = self.rng.integers(0, len(self.obs), size=min(self.batch_size, len(self.obs)))
            x = torch.as_tensor(venv.normalize_obs(self.obs[idx]), dtype=torch.float32, device=model.device)
            y = torch.as_tensor(self.act[idx], dtype=torch.float32, device=model.device)
            loss = torch.nn.functional.mse_loss(pol.get_distribution(x).distribution.mean, y)
            pol.optimizer.zero_grad()
            (self.coef * loss).backward()
            torch.nn.utils.clip_grad_norm_(pol.parameters(), model.max_grad_norm)
            pol.optimizer.step()
            total += loss.item()
        return total / max(self.batches, 1)


# ------------------------------------------------------------------------------ training
def train(args: Args) -> Path:
    import numpy as np
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    from parcover_env.harness.training import RunRecord, plot_curve, write_csv

    if args.init and args.resume:
        raise SystemExit("--init and --resume exclude each other: start from a network, or continue a run")
    run = RunRecord.start(__file__, _ARGV)  # the code that ran, even if HEAD moves during the run
    torch.set_num_threads(args.threads)
    device = ("cuda" if torch.cuda.is_available() else "cpu") if args.device == "auto" else args.device
    out = Path(args.out)
    (out / "checkpoints").mkdir(parents=True, exist_ok=True)
    stages = load_stages(args)
    try:
        import tensorboard  # noqa: F401

        tb_dir = str(out / "tb")
    except ImportError:
        tb_dir = None
    t0 = time.time()
    curve: list[dict] = []
    evals: list[dict] = []
    info: dict = {"stages": stages, "preset": args.preset, "seed": args.seed, "device": device,
                  "args": asdict(args), "train_seeds": [], "eval_seeds": []}

    class Hooks(BaseCallback):
        def __init__(self, stage_idx: int, stage: dict, stage_t0: float):
            super().__init__()
            self.stage_idx, self.stage, self.stage_t0 = stage_idx, stage, stage_t0
            self.next_eval = (model.num_timesteps // args.eval_freq + 1) * args.eval_freq if args.eval_freq else None
            self.next_ckpt = ((model.num_timesteps // args.checkpoint_freq + 1) * args.checkpoint_freq
                              if args.checkpoint_freq else None)
            self.next_print = model.num_timesteps + 20_000

        def _on_rollout_start(self) -> None:
            if frozen and model.num_timesteps >= args.vf_warmup:
                set_actor_trainable(model, True)
                frozen.clear()
                print(f"value warm-up over at {model.num_timesteps} agent-steps: the actor learns", flush=True)

        def _on_rollout_end(self) -> None:
            if bc_reg is not None:
                mse = bc_reg.step(model, venv)
                self.logger.record("train/bc_regularizer_mse", mse)

        def _on_step(self) -> bool:
            for inf, done in zip(self.locals["infos"], self.locals["dones"], strict=False):
                if done and "episode" in inf:
                    m = inf.get("metrics", {})
                    curve.append({"timesteps": self.num_timesteps, "wall_time": time.time() - t0,
                                  "stage": self.stage_idx, "return": inf["episode"]["r"],
                                  "length": inf["episode"]["l"], "success": float(m.get("success", 0.0)),
                                  "kpoi_fraction": m.get("kpois_visited", 0) / max(m.get("n_kpois", 1), 1)})
            n = self.num_timesteps
            if self.next_ckpt is not None and n >= self.next_ckpt:
                self.next_ckpt += args.checkpoint_freq
                model.save(out / "checkpoints" / f"step_{n}.zip")
                venv.save(str(out / "checkpoints" / f"step_{n}_vecnormalize.pkl"))
            if self.next_eval is not None and n >= self.next_eval:
                self.next_eval += args.eval_freq
                run_eval(self.stage_idx, self.stage)
            if n >= self.next_print:
                self.next_print = n + 20_000
                recent = curve[-20:]
                kf = np.mean([c["kpoi_fraction"] for c in recent]) if recent else float("nan")
                print(f"stage {self.stage_idx} {n} steps, {time.time() - t0:.0f} s, {len(curve)} episodes, "
                      f"KPOI fraction (last 20) {kf:.2f}", flush=True)
            now = time.time()
            if args.max_wall_time and now - t0 > args.max_wall_time:
                return False
            return not (self.stage["wall_time"] and now - self.stage_t0 > self.stage["wall_time"])

    best: dict = {}

    def run_eval(stage_idx: int, stage: dict) -> None:
        """Validation episodes now; the network is kept in OUT/best/ when its score is the best so far."""
        n = int(model.num_timesteps)
        rows = evaluate(model, venv, eval_scenarios_for(args, stage), args)
        for r in rows:
            evals.append({"timesteps": n, "wall_time": time.time() - t0, "stage": stage_idx, **r})
        score = (float(np.mean([r["kpoi_fraction"] for r in rows])), float(np.mean([r["success"] for r in rows])))
        print(f"  eval @ {n}: success {score[1]:.2f}, KPOI fraction {score[0]:.2f}", flush=True)
        write_csv(out / "eval.csv", evals)
        if args.keep_best and (not best or score > best["score"]):
            best.update(score=score, timesteps=n)
            (out / "best").mkdir(exist_ok=True)
            model.save(out / "best" / "model.zip")
            venv.save(str(out / "best" / "vecnormalize.pkl"))
            run.write_sidecar(out / "best" / "model.json",
                          {**info, "timesteps": n, "wall_time_s": time.time() - t0, "selected_by": "validation",
                           "selected_from_run": str(out),
                           "validation": rows, "validation_score": {"kpoi_fraction": score[0], "success": score[1]},
                           "eval_seeds": sorted({e["seed"] for e in evals}),
                           "validation_scenarios": sorted({e["scenario"] for e in evals})})
            print(f"  new best @ {n}", flush=True)

    model, venv, prev_stats, bc_reg = None, None, None, None
    frozen: list[bool] = []
    demos: list[dict] | None = None
    start_stage, into_stage = 0, 0
    if args.resume:
        import pickle

        path = Path(args.resume)
        mz = path / "model.zip" if path.is_dir() else path
        model = PPO.load(str(mz), device=device)
        stats = mz.with_name("vecnormalize.pkl" if mz.stem == "model" else mz.stem + "_vecnormalize.pkl")
        with open(stats, "rb") as fh:
            old = pickle.load(fh)
        prev_stats = (old.obs_rms, old.ret_rms)
        info["resumed_from"] = {"model": str(mz), "num_timesteps": int(model.num_timesteps)}
        start_stage, into_stage = len(stages), 0
        done = 0
        for k, st in enumerate(stages):  # the stage the checkpoint is in, and how far into it
            if done + st["steps"] > model.num_timesteps:
                start_stage, into_stage = k, model.num_timesteps - done
                break
            done += st["steps"]
    for si, stage in enumerate(stages):
        if si < start_stage:
            continue
        if args.max_wall_time and time.time() - t0 > args.max_wall_time:
            break
        scen = stage_scenarios(stage["scenario"], stage["n_envs"], args.map_seed0 + 100 * si)
        train_seed = args.seed + 10 * si
        if venv is not None:
            prev_stats = (venv.obs_rms, venv.ret_rms)
            venv.close()
        venv = make_venv(args, scen, train_seed)
        info["train_seeds"].append({"stage": si, "scenarios": scen, "episode_seeds_from": train_seed})
        if prev_stats is not None:  # the normalization carries over from stage to stage
            venv.obs_rms, venv.ret_rms = prev_stats
        if model is None and args.init:
            model, stats = load_init(args, venv, device, tb_dir)
            venv.obs_rms, venv.ret_rms = stats
            info["init_from"] = args.init
            if args.vf_warmup:
                set_actor_trainable(model, False)
                frozen.append(True)
        if model is None:
            policy_kwargs: dict = {"net_arch": [int(h) for h in args.net_arch.split(",")],
                                   "log_std_init": args.log_std_init}
            if args.drop_obs:
                policy_kwargs.update(obs_selection(args, scen[0]))
                info["obs_kept"] = policy_kwargs["features_extractor_kwargs"]["keep"]
            model = PPO("MlpPolicy", venv, n_steps=args.n_steps, batch_size=args.batch_size,
                        n_epochs=args.n_epochs, learning_rate=args.learning_rate, gamma=args.gamma,
                        gae_lambda=args.gae_lambda, ent_coef=args.ent_coef, seed=args.seed, device=device,
                        clip_range=args.clip_range, target_kl=args.target_kl or None,
                        verbose=0, tensorboard_log=tb_dir, policy_kwargs=policy_kwargs)
            if args.bc_episodes or args.bc_datasets:
                demos, source = load_demos(args, args.bc_scenario or stage["scenario"])
                info.update(source)
                info.update(bc_initialize(model, venv, args, demos))
                (out / "bc_init").mkdir(exist_ok=True)
                model.save(out / "bc_init" / "model.zip")
                venv.save(str(out / "bc_init" / "vecnormalize.pkl"))
                run.write_sidecar(out / "bc_init" / "model.json",
                              {**info, "timesteps": 0, "wall_time_s": time.time() - t0})
                print(f"BC init: {info['bc_samples']} samples, action MSE {info['bc_action_mse']:.4f}", flush=True)
        else:
            model.set_random_seed(train_seed)
            _switch_env(model, venv)
        if args.bc_coef and bc_reg is None:
            if demos is None:
                demos, source = load_demos(args, args.bc_scenario or stage["scenario"])
                info.update(source)
            bc_reg = BCRegularizer(demos, args.bc_coef, args.bc_batches, args.batch_size, args.seed)
        if args.eval_freq and args.keep_best and not best:
            run_eval(si, stage)  # the starting network competes for OUT/best/
        remaining = stage["steps"] - (into_stage if si == start_stage else 0)
        print(f"stage {si}: {stage['scenario']} ({len(scen)} envs, {venv.num_envs} slots), {remaining} steps",
              flush=True)
        model.learn(total_timesteps=max(remaining, 1), callback=Hooks(si, stage, time.time()),
                    reset_num_timesteps=False, tb_log_name="ppo")
    if venv is None:
        raise SystemExit(f"nothing to train: {args.resume} already completed every stage")
    wall = time.time() - t0
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    if args.eval_freq and (not evals or evals[-1]["timesteps"] != model.num_timesteps):
        run_eval(len(stages) - 1, stages[-1])
    venv.close()
    info["eval_seeds"] = sorted({e["seed"] for e in evals})
    write_csv(out / "eval.csv", evals)
    write_csv(out / "curve.csv", curve)
    plot_curve(out)
    if best:
        info["best"] = {"timesteps": best["timesteps"], "kpoi_fraction": best["score"][0], "success": best["score"][1]}
        print(f"best validation score at {best['timesteps']} agent-steps: KPOI fraction {best['score'][0]:.2f}, "
              f"success {best['score'][1]:.2f} (OUT/best/)")
    run.write_sidecar(out / "model.json", {**info, "timesteps": int(model.num_timesteps), "wall_time_s": wall,
                                       "training_episodes": len(curve),
                                       "final_eval": evals[-args.eval_episodes * 2:] if evals else []})
    print(f"{model.num_timesteps} agent-steps in {wall:.0f} s")
    return out


def load_init(args: Args, venv, device: str, tb_dir: str | None):
    """The ``args.init`` network on ``venv`` with this run's PPO settings, and its normalization
    statistics ``(obs_rms, ret_rms)``."""
    import pickle

    from stable_baselines3 import PPO

    mz = Path(args.init)
    mz = mz / "model.zip" if mz.is_dir() else mz
    stats = mz.with_name("vecnormalize.pkl" if mz.stem == "model" else mz.stem + "_vecnormalize.pkl")
    # the observation bounds depend on the map (its size): the network does not, so take venv's space
    model = PPO.load(str(mz), env=venv, device=device, custom_objects={"observation_space": venv.observation_space},
                     learning_rate=args.learning_rate, n_steps=args.n_steps,
                     batch_size=args.batch_size, n_epochs=args.n_epochs, clip_range=args.clip_range,
                     target_kl=args.target_kl or None, ent_coef=args.ent_coef, gamma=args.gamma,
                     gae_lambda=args.gae_lambda, seed=args.seed, tensorboard_log=tb_dir)
    model.num_timesteps = 0
    with open(stats, "rb") as fh:
        old = pickle.load(fh)
    return model, (old.obs_rms, old.ret_rms)


def set_actor_trainable(model, on: bool) -> None:
    """Freeze (``on=False``) or unfreeze the actor of an SB3 actor-critic policy: its hidden layers,
    action head and log-std; the value network always learns."""
    import torch

    pol = model.policy
    params = [*pol.mlp_extractor.policy_net.parameters(), *pol.action_net.parameters()]
    if isinstance(getattr(pol, "log_std", None), torch.nn.Parameter):
        params.append(pol.log_std)
    for prm in params:
        prm.requires_grad_(on)


def obs_selection(args: Args, scenario: str) -> dict:
    """``policy_kwargs`` entries that hide the fields ``args.drop_obs`` from the networks."""
    from parcover_env.harness.sb3_training import observation_selection

    return observation_selection(scenario, args.preset, args.drop_obs)


def _switch_env(model, venv) -> None:
    """Point a PPO model at a new VecEnv (another stage: maybe another number of slots)."""
    model.env = venv
    model.n_envs = venv.num_envs
    model._vec_normalize_env = venv
    model._last_obs = None  # learn() resets the new env
    model.rollout_buffer = model.rollout_buffer_class(
        model.n_steps, model.observation_space, model.action_space, device=model.device, gamma=model.gamma,
        gae_lambda=model.gae_lambda, n_envs=model.n_envs, **model.rollout_buffer_kwargs)


if __name__ == "__main__":
    a = parse_args()
    print(f"wrote {train(a)}")
