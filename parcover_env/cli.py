"""The ``parcover`` command line: run missions, list scenarios, draw plans and sensor views."""

from __future__ import annotations

import argparse
import sys
import time
from parcover_env.errors import ParcoverError

__all__ = ["main"]


def _progress(done: int, total: int, width: int = 30, stream=sys.stderr) -> None:
    if not stream.isatty() and done not in (total,) and done % max(total // 10, 1):
        return
    filled = int(width * done / max(total, 1))
    stream.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} steps")
    if done >= total:
        stream.write("\n")
    stream.flush()


def make_policy(name: str, env, seed: int | None):
    """A policy object with ``act(observations) -> actions`` by CLI name."""
    from parcover_env.policies import RandomPolicy, WaypointPolicy

    if name == "random":
        return RandomPolicy(seed)
    if name == "waypoint":
        return WaypointPolicy(env.layout)
    if name == "expert":
        from parcover_env.expert.policy import ScriptedExpert

        return ScriptedExpert.for_env(env)
    raise ParcoverError(f"--policy: unknown policy '{name}' (choose from {', '.join(POLICIES)})")


POLICIES = ("expert", "waypoint", "random")


def run_episode(env, policy, seed: int | None, max_steps: int | None = None, frames: list | None = None,
                progress: bool = False) -> dict:
    """Run one episode; returns the episode metrics (plus wall time)."""
    obs, _ = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset(obs)
    limit = max_steps or env.scenario.episode.max_steps
    summary, t0, step = None, time.perf_counter(), 0
    if frames is not None:
        frames.append(env.render())
    while env.agents and step < limit:
        obs, _, _, _, infos = env.step(policy.act(obs))
        step += 1
        if frames is not None:
            frames.append(env.render())
        if progress:
            _progress(step, limit)
        if not env.agents:
            summary = next(iter(infos.values()))["episode"]
    if progress and step < limit:
        _progress(limit, limit)
    if summary is None:
        summary = env.metrics.summary()
    summary["wall_time"] = time.perf_counter() - t0
    if hasattr(policy, "stats"):
        summary.update(policy.stats())
    return summary


def _format_metrics(m: dict) -> str:
    rows = []
    for key, value in m.items():
        if isinstance(value, float):
            value = f"{value:.3f}"
        elif isinstance(value, list):
            value = "[" + ", ".join(f"{v:.2f}" if isinstance(v, float) else str(v) for v in value) + "]"
        rows.append((key, str(value)))
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"  {k:<{width}}  {v}" for k, v in rows)


def cmd_run(args) -> int:
    from parcover_env import parallel_env
    from parcover_env.render import save_gif

    env = parallel_env(args.scenario, render_mode="rgb_array" if args.gif else None)
    policy = make_policy(args.policy, env, args.seed)
    frames = [] if args.gif else None
    print(f"scenario {env.scenario.name}: {env.n_robots} robots, {len(env.scenario.kpois)} KPOIs, "
          f"policy {args.policy}, seed {args.seed}")
    m = run_episode(env, policy, args.seed, args.steps, frames, progress=not args.quiet)
    print(_format_metrics(m))
    if frames:
        save_gif(args.gif, frames[:: max(1, args.gif_every)], fps=max(1, 10 // max(1, args.gif_every)))
        print(f"wrote {args.gif} ({len(frames[:: max(1, args.gif_every)])} frames)")
    return 0 if m["success"] or args.allow_failure else 1


def cmd_scenarios(args) -> int:
    from parcover_env.config import load_scenario, scenario_names

    for name in scenario_names():
        s = load_scenario(name)
        print(f"{name:<10} {s.description}  [{len(s.kpois)} KPOIs, n_robots={s.n_robots}, "
              f"{len(s.kinects)} Kinects, map {s.map.size[0]} x {s.map.size[1]} m]")
    return 0


def cmd_render(args) -> int:
    import cv2

    from parcover_env import parallel_env

    env = parallel_env(args.scenario, render_mode="rgb_array")
    env.reset(seed=args.seed)
    cv2.imwrite(args.png, cv2.cvtColor(env.render(), cv2.COLOR_RGB2BGR))
    print(f"wrote {args.png}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="parcover", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run one mission and print its metrics")
    r.add_argument("scenario", nargs="?", default="office", help="scenario name or YAML path (default: office)")
    r.add_argument("--seed", type=int, default=0, help="episode seed (default: 0)")
    r.add_argument("--steps", type=int, default=None, help="stop after N steps (default: the scenario's limit)")
    r.add_argument("--policy", choices=POLICIES, default="expert", help="who drives (default: expert)")
    r.add_argument("--gif", default=None, help="write an animated GIF of the episode here")
    r.add_argument("--gif-every", type=int, default=2, help="keep every k-th frame in the GIF (default: 2)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--allow-failure", action="store_true", help="exit 0 even if not every KPOI was visited")
    r.set_defaults(func=cmd_run)
    s = sub.add_parser("scenarios", help="list the shipped scenarios")
    s.set_defaults(func=cmd_scenarios)
    f = sub.add_parser("render", help="write the first frame of a scenario as a PNG")
    f.add_argument("scenario", nargs="?", default="office")
    f.add_argument("--png", default="frame.png", help="output file (default: frame.png)")
    f.add_argument("--seed", type=int, default=0)
    f.set_defaults(func=cmd_render)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ParcoverError as exc:
        print(f"parcover: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
