"""Odometry drift and drive response under the realistic defaults (issue 13's calibration).

1. Drive response: steps (0.1 s each) from rest to 90 % of max speed at full forward, and the
   speed after the first step.
2. Straight drive on pure odometry (``pose_source: odometry``, no Kinect): one robot on an empty
   14 m x 3 m floor drives full forward; after 100 steps and after 10 m of true travel, the median
   (and p90) over the seeds of the heading error (deg) and of the position error as % of the
   distance travelled.
3. With Kinect localization (``office``, the scripted expert, ``pose_source: kinect``): the pose
   error of the leaders right after a Kinect fix (fix age <= 0.2 s) and of every robot overall,
   against the same runs on pure odometry.

    .venv/bin/python benchmarks/odometry_drift.py [--seeds 20] [--expert-seeds 3]
"""

from __future__ import annotations

import argparse

import numpy as np

import parcover_env
from parcover_env.expert import expert_for

FLOOR = {
    "map": {"size": [14.0, 3.0], "walls": [], "obstacles": [], "unknown_obstacles": []},
    "start": {"x": 1.0, "y": 1.5, "theta_deg": 0.0}, "start_queue": [], "kpois": [[13.5, 1.5]],
    "kinects": [], "n_robots": 1, "observation": {"pose_source": "odometry"}, "episode": {"max_steps": 2000},
}


def drive_response() -> tuple[int, float, float]:
    env = parcover_env.parallel_env("office", overrides={"n_robots": 1, "observation": {"pose_source": "odometry"}})
    env.reset(seed=0)
    v_max = env.scenario.robot.max_speed
    speeds = []
    for _ in range(20):
        env.step({"robot_0": np.array([1.0, 0.0], np.float32)})
        speeds.append(float(env.world.drive.wheels[0].mean()))
    first = speeds[0] / v_max
    steps90 = next(i + 1 for i, s in enumerate(speeds) if s >= 0.9 * v_max)
    return steps90, first, v_max


def straight(seed: int, distance: float = 10.0, probe_steps: int = 100) -> dict:
    env = parcover_env.parallel_env("office", overrides=FLOOR)
    env.reset(seed=seed)
    start = env.true_poses()[0].copy()
    out, steps = {}, 0
    while True:
        env.step({"robot_0": np.array([1.0, 0.0], np.float32)})
        steps += 1
        true, est = env.true_poses()[0], env.pose_estimates()[0]
        travelled = float(np.hypot(*(true[:2] - start[:2])))
        key = "100 steps" if steps == probe_steps else "10 m" if travelled >= distance else None
        if key:
            err = float(np.hypot(*(est[:2] - true[:2])))
            dth = float(np.degrees(abs((est[2] - true[2] + np.pi) % (2 * np.pi) - np.pi)))
            sig = np.sqrt(np.linalg.eigvalsh(env.pose_covariances()[0][:2, :2]).max())
            out[key] = (dth, 100 * err / travelled, travelled, err / sig)
        if travelled >= distance:
            return out


def expert_errors(pose_source: str, seeds: int) -> tuple[list[float], list[float]]:
    fixed, overall = [], []
    for seed in range(seeds):
        env = parcover_env.parallel_env("office", overrides={"observation": {"pose_source": pose_source}})
        obs, _ = env.reset(seed=seed)
        policy = expert_for(env)
        while env.agents:
            obs, _, _, _, infos = env.step(policy.act(obs))
            fresh = (env.fix_age <= 0.2 + 1e-9) & env.team.leader
            for i, a in enumerate(env.possible_agents):
                if a in infos:
                    overall.append(infos[a]["pose_error"])
                    if fresh[i]:
                        fixed.append(infos[a]["pose_error"])
    return fixed, overall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--expert-seeds", type=int, default=3)
    args = ap.parse_args()

    steps90, first, v_max = drive_response()
    print(f"drive: full forward from rest reaches {100 * first:.0f} % of max speed ({v_max} m/s) after one "
          f"step; 90 % after {steps90} steps ({0.1 * steps90:.1f} s)")

    runs = [straight(s) for s in range(args.seeds)]
    print(f"straight drive on pure odometry, {args.seeds} seeds (median / p90):")
    for key in ("100 steps", "10 m"):
        a = np.array([r[key] for r in runs])
        print(f"  {key:>9} ({np.median(a[:, 2]):.2f} m): heading error {np.median(a[:, 0]):.2f} / "
              f"{np.percentile(a[:, 0], 90):.2f} deg, position error {np.median(a[:, 1]):.2f} / "
              f"{np.percentile(a[:, 1], 90):.2f} % of distance, error / covariance sigma_major "
              f"{np.median(a[:, 3]):.2f} / {np.percentile(a[:, 3], 90):.2f}")

    if args.expert_seeds:
        for source in ("kinect", "odometry"):
            fixed, overall = expert_errors(source, args.expert_seeds)
            line = f"office expert, pose_source {source:>8}, {args.expert_seeds} seeds: pose error median / p90 "
            line += f"{100 * np.median(overall):.1f} / {100 * np.percentile(overall, 90):.1f} cm (all robots)"
            if source == "kinect":
                line += f", {100 * np.median(fixed):.1f} / {100 * np.percentile(fixed, 90):.1f} cm (leaders just fixed)"
            print(line)


if __name__ == "__main__":
    main()
