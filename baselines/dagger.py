"""DAgger into a PPO network: a teacher labels the states the learner reaches, across many maps.

    python baselines/dagger.py --teacher waypoint --map-seed0 200 --n-maps 40 \
        --driver-probs 0,0.5,0.8,1 --drop-obs x,y,cos_theta,sin_theta --out runs/dagger_generated

Round 0 records the teacher driving on maps ``generated:<map_seed0 + k>`` (``--n-maps``, episode
seeds ``seed0 + k``); every later round r lets the network of round r-1 drive on a fraction
``driver_probs[r]`` of the steps while the teacher labels every step (Ross et al. 2011,
:func:`parcover_env.harness.datasets.record_episodes`), on fresh episode seeds of the same maps.
After each round the actor is refit from scratch on all rounds' data (mean action, MSE) and the
critic on the discounted returns (:func:`parcover_env.harness.sb3_training.bc_initialize`); the result is an
SB3 PPO model (``OUT/round_<r>/model.zip`` + ``vecnormalize.pkl`` + ``model.json``), a ``--policies ppo:PATH``
policy that ``train_ppo.py --resume`` can fine-tune. Each round is scored on validation maps
(``--val-scenarios``, seeds ``val_seed0 ..``, disjoint from training maps and from the benchmark's
maps/seeds >= 1000); the best round (mean KPOI fraction, then success; earlier wins ties) is copied
to ``OUT/`` (model.zip, vecnormalize.pkl, model.json). With ``--dataset-root`` each round's data is
also written as Minari datasets (``parcover/dagger-<teacher>-r<r>-v0``) for ``train_ppo.py
--bc-datasets`` (the BC regularizer of a PPO phase).

Why a teacher other than the scripted expert: the expert's actions depend on state the observation
does not carry (its plan, waits for teammates and for localization fixes), so a network cloning it
from the observation averages "drive" and "wait" in the same observed state and stalls (measured in
docs/lab/train_and_compare.md). ``waypoint`` acts from the observation alone, so it can be cloned exactly.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))


@dataclass
class Args:
    teacher: str = "waypoint"
    """Policy spec that labels every step (``waypoint``, ``expert``, ...)."""
    map_seed0: int = 200
    """First training map ``generated:<map_seed0>``."""
    n_maps: int = 40
    """Training maps per round (``map_seed0 .. map_seed0 + n_maps - 1``), one episode each."""
    seed0: int = 0
    """Episode seed of map k in round r: ``seed0 + 100 * r + k`` (training seeds, < 500)."""
    driver_probs: str = "0,0.5,0.8,1"
    """Per round: fraction of the steps the previous round's network drives (round 0 must be 0)."""
    max_steps: int = 0
    """Override episode.max_steps while recording (0 = the scenario's)."""
    preset: str = "realistic"
    workers: int = 2
    """Recording processes."""
    bc_epochs: int = 20
    learning_rate: float = 1e-3
    """Adam step size of the BC fit."""
    net_arch: str = "128,128"
    drop_obs: str = "x,y,cos_theta,sin_theta"
    """Observation fields hidden from the networks (the world-frame pose: meaningless on unseen maps)."""
    gamma: float = 0.995
    bc_log_std: float = -1.0
    seed: int = 0
    """Seeds torch (BC minibatch order, network initialization)."""
    val_scenarios: str = "generated:500,generated:501,generated:502,generated:503"
    val_seed0: int = 500
    dataset_root: str = ""
    """Also write each round's data as Minari datasets under this root ('' = do not)."""
    out: str = "runs/dagger"
    threads: int = 1


_ARGV: list[str] = []
"""The arguments ``parse_args`` read (written into the sidecars' command)."""


def parse_args(argv=None) -> Args:
    import tyro

    _ARGV[:] = list(sys.argv[1:] if argv is None else argv)
    return tyro.cli(Args, args=argv, description=__doc__)


def driver_schedule(spec: str) -> list[float]:
    """The per-round driver fractions; round 0 has no network yet, so it must be 0."""
    probs = [float(p) for p in spec.split(",") if p.strip()]
    if not probs or probs[0] != 0.0 or any(not 0.0 <= p <= 1.0 for p in probs):
        raise ValueError(f"driver_probs '{spec}': first entry 0, every entry in [0, 1]")
    return probs


def _record(job: tuple) -> list:
    scenario, seed, teacher, driver, prob, max_steps, preset = job
    import torch

    from parcover_env.harness.datasets import record_episodes

    torch.set_num_threads(1)
    return record_episodes(scenario, 1, seed=seed, policy=teacher, max_steps=max_steps or None,
                           preset=preset, driver=driver, driver_prob=prob)


def collect_round(args: Args, rnd: int, driver: str | None, prob: float) -> list:
    """One episode per training map; the teacher labels, ``driver`` acts on ``prob`` of the steps."""
    jobs = [(f"generated:{args.map_seed0 + k}", args.seed0 + 100 * rnd + k, args.teacher, driver, prob,
             args.max_steps, args.preset) for k in range(args.n_maps)]
    if args.workers <= 1:
        results = [_record(j) for j in jobs]
    else:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(args.workers) as pool:
            results = pool.map(_record, jobs, chunksize=1)
    return [ep for eps in results for ep in eps]


def fit(args: Args, eps: list, out: Path, info: dict) -> Path:
    """A fresh PPO network cloned on ``eps``; saved as ``out/model.zip`` + stats + sidecar."""
    import torch
    from stable_baselines3 import PPO

    from parcover_env.harness.sb3_training import bc_initialize, make_sb3_venv, observation_selection

    scenario = f"generated:{args.map_seed0}"
    torch.manual_seed(args.seed)
    venv = make_sb3_venv([scenario], args.seed, preset=args.preset, gamma=args.gamma)
    policy_kwargs: dict = {"net_arch": [int(h) for h in args.net_arch.split(",")]}
    if args.drop_obs:
        policy_kwargs.update(observation_selection(scenario, args.preset, args.drop_obs))
    model = PPO("MlpPolicy", venv, seed=args.seed, device="cpu", gamma=args.gamma, verbose=0,
                policy_kwargs=policy_kwargs)
    stats = bc_initialize(model, venv, eps, gamma=args.gamma, seed=args.seed, epochs=args.bc_epochs,
                          log_std=args.bc_log_std, learning_rate=args.learning_rate)
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    venv.close()
    info.update(stats)
    return out / "model.zip"


def validate(args: Args, model_zip: Path) -> list[dict]:
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.learned import PPOPolicy

    rows = []
    for k, sc in enumerate(s for s in args.val_scenarios.split(",") if s):
        env = ParallelCoverageEnv(sc, preset=args.preset)
        m = run_episode(env, PPOPolicy(model_zip), args.val_seed0 + k)
        rows.append({"scenario": sc, "seed": args.val_seed0 + k, "success": float(m["success"]),
                     "kpoi_fraction": m["kpois_visited"] / m["n_kpois"], "collisions": m["collisions"]})
        env.close()
    return rows


def run(args: Args) -> Path:
    import numpy as np
    import torch

    from parcover_env.harness.training import RunRecord, write_csv

    torch.set_num_threads(args.threads)
    record = RunRecord.start(__file__, _ARGV)  # the code that ran, even if HEAD moves during the run
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    probs = driver_schedule(args.driver_probs)
    t0 = time.time()
    data: list = []
    history: list[dict] = []
    best: dict = {}
    driver: str | None = None
    for rnd, prob in enumerate(probs):
        t_round = time.time()
        eps = collect_round(args, rnd, driver if prob > 0 else None, prob)
        t_rec = time.time() - t_round
        if args.dataset_root:
            from parcover_env.harness.datasets import save_minari

            ds = f"parcover/dagger-{args.teacher}-r{rnd}-v0"
            save_minari(eps, ds, args.dataset_root, f"generated:{args.map_seed0}",
                        algorithm=f"{args.teacher} labels, previous round drives {prob:.0%} of steps")
        data += eps
        rdir = out / f"round_{rnd}"
        info: dict = {"round": rnd, "teacher": args.teacher, "driver": driver if prob > 0 else None,
                      "driver_prob": prob, "args": asdict(args), "preset": args.preset,
                      "train_maps": [args.map_seed0, args.map_seed0 + args.n_maps - 1],
                      "episode_seeds": [args.seed0 + 100 * r for r in range(rnd + 1)],
                      "seed": args.seed, "robot_episodes": len(data), "record_wall_time_s": t_rec}
        model_zip = fit(args, data, rdir, info)
        rows = validate(args, model_zip)
        score = (float(np.mean([r["kpoi_fraction"] for r in rows])), float(np.mean([r["success"] for r in rows])))
        info.update(validation=rows, eval_seeds=sorted({r["seed"] for r in rows}),
                    validation_score={"kpoi_fraction": score[0], "success": score[1]},
                    timesteps=0, wall_time_s=time.time() - t0, round_wall_time_s=time.time() - t_round)
        record.write_sidecar(rdir / "model.json", info)
        history.append({"round": rnd, "driver_prob": prob, "samples": info["bc_samples"],
                        "bc_action_mse": info["bc_action_mse"], "val_kpoi_fraction": score[0],
                        "val_success": score[1], "wall_time_s": time.time() - t0})
        print(f"round {rnd}: {info['bc_samples']} samples, action MSE {info['bc_action_mse']:.4f}, "
              f"validation KPOI {score[0]:.2f} success {score[1]:.2f}, {time.time() - t0:.0f} s", flush=True)
        if not best or score > best["score"]:
            best = {"score": score, "round": rnd}
        driver = f"ppo:{model_zip}"
    src = out / f"round_{best['round']}"
    for name in ("model.zip", "vecnormalize.pkl"):
        shutil.copy(src / name, out / name)
    rec = json.loads((src / "model.json").read_text())
    rec.update(selected_by="validation", history=history, best_round=best["round"], wall_time_s=time.time() - t0)
    (out / "model.json").write_text(json.dumps(rec, indent=2, default=str) + "\n")
    write_csv(out / "history.csv", history)
    print(f"best round {best['round']} -> {out / 'model.zip'} ({time.time() - t0:.0f} s)")
    return out


if __name__ == "__main__":
    run(parse_args())
