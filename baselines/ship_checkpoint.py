"""Copy a trained PPO run into ``baselines/checkpoints/`` as a small, self-describing checkpoint.

    python baselines/ship_checkpoint.py --run runs/ppo_tree --name ppo_tree --scenario tree

Writes ``NAME.zip`` (the SB3 model, with its optimizer state so that ``--resume`` works),
``NAME_vecnormalize.pkl`` (observation statistics) and ``NAME.json``: the run's sidecars (following
``--resume`` chains back to the BC initialization, oldest last) plus a
reproducibility check, the deterministic action of every robot for the first observation of
``SCENARIO`` at seed 1000, which ``tests/policies/test_checkpoints.py`` compares on load.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent


@dataclass
class Args:
    run: str
    """A train_ppo.py output directory (model.zip, vecnormalize.pkl, model.json) or a model .zip."""
    name: str = "ppo_office"
    scenario: str = "office"
    """Scenario of the reproducibility check (and the one the policy is meant for)."""
    preset: str = "realistic"
    out: str = str(HERE / "checkpoints")


def check_record(model_zip: Path, scenario: str, preset: str, seed: int = 1000) -> dict:
    """First observation of ``scenario`` at ``seed`` and the policy's deterministic actions for it."""
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.policies.learned import PPOPolicy

    env = ParallelCoverageEnv(scenario, preset=preset)
    obs, _ = env.reset(seed=seed)
    act = PPOPolicy(model_zip).act(obs)
    return {"scenario": scenario, "preset": preset, "seed": seed,
            "observations": {a: obs[a].tolist() for a in sorted(obs)},
            "actions": {a: act[a].tolist() for a in sorted(act)}}


def sidecar_chain(model_zip: Path) -> list[dict]:
    """The sidecar of the run that wrote ``model_zip``, then those of the runs it resumed from and of
    their BC initialization, newest first; for a network kept by validation (``OUT/best/``), the
run's final sidecar and its BC initialization follow."""
    chain, seen = [], set()
    todo = [model_zip.parent / "model.json"]
    while todo:
        side = todo.pop(0).resolve()
        if side in seen or not side.is_file():
            continue
        seen.add(side)
        rec = json.loads(side.read_text())
        chain.append({"file": side.name, **rec})
        if "resumed_from" in rec:
            todo.append(Path(rec["resumed_from"]["model"]).parent / "model.json")
        if "selected_from_run" in rec:  # OUT/best/: the whole run (its final sidecar) and its BC init
            run = Path(rec["selected_from_run"])
            todo += [run / "model.json", run / "bc_init" / "model.json"]
        todo.append(side.parent / "bc_init" / "model.json")
    return chain


def ship(args: Args) -> Path:
    from parcover_env.policies.learned import vecnormalize_file

    run = Path(args.run)
    model_zip = run / "model.zip" if run.is_dir() else run
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    dst = out / f"{args.name}.zip"
    shutil.copy(model_zip, dst)
    shutil.copy(vecnormalize_file(model_zip), out / f"{args.name}_vecnormalize.pkl")
    record = {"name": args.name, "source_run": str(run), "sidecars": sidecar_chain(model_zip),
              "check": check_record(dst, args.scenario, args.preset)}
    (out / f"{args.name}.json").write_text(json.dumps(record, indent=1) + "\n")
    return dst


def parse_args(argv=None) -> Args:
    import tyro

    return tyro.cli(Args, args=argv, description=__doc__)


if __name__ == "__main__":
    print(f"wrote {ship(parse_args())}")
