"""parcover: run parallel path coverage missions, list scenarios, draw plans and sensor views.

Bad input (an unknown scenario, a negative seed, a path that cannot be written, a missing optional
dependency) is reported as one line "parcover: error: ..." with exit status 2.
"""

from __future__ import annotations

import argparse
import math
import sys

from parcover_env.cli.checks import (
    OneLineParser,
    check_writable_dir,
    check_writable_file,
    int_at_most,
    non_negative_int,
    positive_int,
    write_image,
)
from parcover_env.config.schema import MAX_ROBOTS
from parcover_env.errors import OutputError, ParcoverError
from parcover_env.policies.registry import policy_specs

__all__ = ["main", "build_parser"]


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


def _sayer(args):
    """``print`` for human-readable lines: to stderr when ``--json`` owns stdout."""
    stream = sys.stderr if getattr(args, "json", False) else sys.stdout
    return lambda text: print(text, file=stream)


def _finite(obj):
    """Non-finite floats become ``null`` (JSON has no NaN or infinity); numpy scalars become floats."""
    if isinstance(obj, dict):
        return {str(k): _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, str):
        obj = obj.item()
    return obj if not isinstance(obj, float) or math.isfinite(obj) else None


def _print_json(obj) -> None:
    import json

    print(json.dumps(_finite(obj), allow_nan=False))


def _range(text: str) -> float:
    """``--range``: metres > 0, or ``inf`` for unlimited range."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected metres or 'inf', got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0 (or 'inf'), got {text!r}")
    return value


def cmd_run(args) -> int:
    from parcover_env import parallel_env
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.registry import make_policy, policy_overrides
    from parcover_env.viz.render import GifRecorder

    if args.gif:
        check_writable_file(args.gif, "--gif")
        if not args.gif.lower().endswith(".gif"):
            raise OutputError(f"--gif: {args.gif}: expected a file name ending in .gif")
    env = parallel_env(args.scenario, render_mode="rgb_array" if args.gif else None, preset=args.preset,
                       overrides=policy_overrides(args.policy, args.scenario))
    policy = make_policy(args.policy, env, args.seed)
    say = _sayer(args)  # with --json, human-readable lines go to stderr, the JSON object to stdout
    say(f"scenario {env.scenario.name}: {env.n_robots} robots, {len(env.scenario.kpois)} KPOIs, "
        f"policy {args.policy}, seed {args.seed}, preset {args.preset}")
    recorder = GifRecorder(args.gif, every=args.gif_every, fps=max(1, 10 // args.gif_every)) if args.gif else None
    try:
        m = run_episode(env, policy, args.seed, args.steps, recorder, progress=not args.quiet)
    finally:
        if recorder is not None:
            recorder.close()
    if args.json:  # what was run, then the episode metrics
        _print_json({"scenario": env.scenario.name, "seed": args.seed, "policy": args.policy,
                     "preset": args.preset, **m})
    else:
        print(_format_metrics(m))
    if recorder is not None:
        say(f"wrote {args.gif} ({recorder.written} frames)")
    return 0 if m["success"] or args.allow_failure else 1


def cmd_scenarios(args) -> int:
    from parcover_env.scenarios import load_scenario, scenario_names

    for name in scenario_names():
        s = load_scenario(name)
        print(f"{name:<10} {s.description}  [{len(s.kpois)} KPOIs, n_robots={s.n_robots}, "
              f"{len(s.kinects)} Kinects, map {s.map.size[0]} x {s.map.size[1]} m]")
    return 0


def cmd_render(args) -> int:

    from parcover_env import parallel_env

    check_writable_file(args.png, "--png")
    env = parallel_env(args.scenario, render_mode="rgb_array")
    env.reset(seed=args.seed)
    write_image(args.png, env.render(), "--png")
    print(f"wrote {args.png}")
    return 0


def cmd_plan(args) -> int:
    from parcover_env.planning import kinect_footprints, kinect_tree, plan_scenario, plan_summary
    from parcover_env.scenarios import load_scenario
    from parcover_env.viz.plan import draw_plan

    if args.png:
        check_writable_file(args.png, "--png")
    s = load_scenario(args.scenario)
    plan = plan_scenario(s, args.n_robots if args.n_robots is not None else s.n_robots_fixed)
    tree = kinect_tree(kinect_footprints(s), plan, (s.start.x, s.start.y)) if s.kinects else None
    if args.json:
        _print_json(plan_summary(plan, tree))
    else:
        print(f"scenario {s.name}: r = {plan.r} robots, c_max = {plan.c_max:.2f} m, c_p = {plan.c_p:.2f} m "
              f"({plan.method}, roadmap metric); longest route to a KPOI {plan.c_route:.2f} m; free-space "
              f"bound c_free = {plan.c_free:.2f} m; {len(plan.turning_points)} turning positions")
        for tp in plan.turning_points:
            counts = ", ".join(str(b.n_robots) for b in tp.branches)
            print(f"  TP at ({tp.position[0]:.2f}, {tp.position[1]:.2f}): robots {tp.robots[0]}-{tp.robots[1] - 1} "
                  f"split into branches of {counts}")
        if tree is not None:
            links = ", ".join(f"{a}-{b} ({n})" for (a, b), n in sorted(tree.links.items()))
            print(f"  Kinect tree rooted at {tree.root}: links {links or 'none'}")
    if args.png:
        write_image(args.png, draw_plan(s, plan, tree), "--png")
        _sayer(args)(f"wrote {args.png}")
    return 0


def cmd_kinect(args) -> int:
    import numpy as np

    from parcover_env.scenarios import load_scenario
    from parcover_env.viz.kinect_views import write_kinect_views

    check_writable_dir(args.out, "--out")
    paths = write_kinect_views(load_scenario(args.scenario), args.out, np.random.default_rng(args.seed))
    for p in paths:
        print(f"wrote {p}")
    return 0


def cmd_sectors(args) -> int:
    from parcover_env.localization.sonar import compute_sectors, map_features, sectors_summary
    from parcover_env.localization.sonar.sectors import RULE_NAMES
    from parcover_env.scenarios import load_scenario
    from parcover_env.viz.sectors import draw_sectors
    from parcover_env.world.map_model import map_model

    if args.png:
        check_writable_file(args.png, "--png")
    if args.rearrangement:
        check_writable_file(args.rearrangement, "--rearrangement")
    s = load_scenario(args.scenario)
    if args.rearrangement:  # checked before any output is written
        from parcover_env.scenarios import mission_for

        if mission_for(s).n_robots < 2:
            raise ParcoverError(f"--rearrangement: scenario '{s.name}' plans {mission_for(s).n_robots} robot(s); "
                                "Kim, Pearce & Amato Fig. 9 needs two")
    known = map_model(s.map, include_unknown=False)
    features = map_features(known)
    range_max = s.robot.sonar.range_max if args.range is None else args.range
    sectors = compute_sectors(known, range_max, rule=args.rule, features=features)
    if args.json:
        _print_json({"scenario": s.name, **sectors_summary(known, range_max, args.rule, features, sectors)})
    else:
        reach = "unlimited range" if range_max == float("inf") else f"range {range_max} m"
        print(f"scenario {s.name}: {len(features)} features, {len(sectors)} {RULE_NAMES[args.rule]} sectors "
              f"({reach})")
    if args.png:
        write_image(args.png, draw_sectors(known, sectors, features), "--png")
        _sayer(args)(f"wrote {args.png}")
    if args.rearrangement:
        import numpy as np

        from parcover_env.viz.sectors import rearrangement_figure

        img, info = rearrangement_figure(s)
        write_image(args.rearrangement, img, "--rearrangement")
        _sayer(args)(f"wrote {args.rearrangement}: Fig. 9 subgoals "
                     f"{np.round(info['before'], 2).tolist()} -> {np.round(info['after'], 2).tolist()} "
                     f"(min scan angle {info['min_scan_angle_deg_before']:.0f} -> "
                     f"{info['min_scan_angle_deg_after']:.0f} deg)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from parcover_env import __version__

    p = OneLineParser(prog="parcover", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"parcover {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    r = sub.add_parser("run", help="run one mission and print its metrics")
    r.add_argument("scenario", nargs="?", default="office", help="scenario name or YAML path (default: office)")
    r.add_argument("--seed", type=non_negative_int, default=0, help="episode seed (default: 0)")
    r.add_argument("--steps", type=positive_int, default=None, help="stop after N steps (default: scenario's limit)")
    r.add_argument("--policy", default="expert", help=f"who drives: {policy_specs()} (default: expert)")
    r.add_argument("--preset", choices=["realistic", "ideal"], default="realistic",
                   help="error models: realistic (the config's) or ideal (all off) (default: realistic)")
    r.add_argument("--gif", default=None, help="write an animated GIF of the episode here")
    r.add_argument("--gif-every", type=positive_int, default=2, help="keep every k-th frame in the GIF (default: 2)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--allow-failure", action="store_true", help="exit 0 even if not every KPOI was visited")
    r.add_argument("--json", action="store_true", help="print the episode metrics as one JSON object "
                   "(other output goes to stderr)")
    r.set_defaults(func=cmd_run)
    s = sub.add_parser("scenarios", help="list the shipped scenarios")
    s.set_defaults(func=cmd_scenarios)
    f = sub.add_parser("render", help="write the first frame of a scenario as a PNG")
    f.add_argument("scenario", nargs="?", default="office")
    f.add_argument("--png", default="frame.png", help="output file (default: frame.png)")
    f.add_argument("--seed", type=non_negative_int, default=0)
    f.set_defaults(func=cmd_render)
    from parcover_env.cli.bench import add_bench_parser, add_collect_parser
    from parcover_env.cli.train import add_train_parser

    add_bench_parser(sub)
    add_collect_parser(sub)
    add_train_parser(sub)
    pl = sub.add_parser("plan", help="PPCP plan: print r, c_max, c_p and the TPs; draw it")
    pl.add_argument("scenario", nargs="?", default="office")
    pl.add_argument("--png", default=None, help="draw the map, roadmap, plan tree and Kinect tree here")
    pl.add_argument("--n-robots", type=int_at_most(MAX_ROBOTS), default=None,
                    help=f"plan for this many robots, at most {MAX_ROBOTS} (min-max variant)")
    pl.add_argument("--json", action="store_true", help="print n_robots, c_max, turning_positions, "
                    "kinect_tree and routes as one JSON object")
    pl.set_defaults(func=cmd_plan)
    k = sub.add_parser("kinect", help="write the Kinect views: depth, IR, pipeline stages, hull, trajectory")
    k.add_argument("scenario", nargs="?", default="office")
    k.add_argument("--out", default="kinect_views", help="output directory (default: kinect_views/)")
    k.add_argument("--seed", type=non_negative_int, default=0)
    k.set_defaults(func=cmd_kinect)
    se = sub.add_parser("sectors", help="sonar visibility sectors of a map (Kim, Pearce & Amato Fig. 3/4)")
    se.add_argument("scenario", nargs="?", default="t_room")
    se.add_argument("--rule", type=int, choices=(0, 1, 2), default=2, help="0 original, 1 or 2 merge rule")
    se.add_argument("--png", default=None, help="draw the sectors here")
    se.add_argument("--range", type=_range, default=None, metavar="R|inf",
                    help="sonar range in metres, or inf (default: the scenario's sonar range_max)")
    se.add_argument("--json", action="store_true", help="print features and sectors as one JSON object")
    se.add_argument("--rearrangement", default=None, metavar="PNG",
                    help="draw Kim, Pearce & Amato Fig. 9(a)->(b) here: two robots' subgoals before/after the bisector "
                    "rearrangement")
    se.set_defaults(func=cmd_sectors)
    return p


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 = bad input, reported in one line)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help, --version (0) and argument errors (2, already printed)
        return int(exc.code or 0)
    try:
        return args.func(args)
    except ParcoverError as exc:
        print(f"parcover: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file the user named cannot be read or written
        print(f"parcover: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
