"""Accuracy and throughput of the synthetic Kinect + marker pipeline (seed A Fig. 10 setting).

One robot (unicycle, no env) drives arcs under a Kinect looking straight down at the paper's two
speed settings, (v, omega) = (0.015 m/s, 0.023 rad/s) and (0.08, 0.08); every Kinect frame is
rendered and run through the full pipeline. Prints position / heading RMSE, detection rate and
ms per frame (render, pipeline) at 320x240 and 640x480, the fast path's calibrated noise, and saves
the Fig. 10 style plot to benchmarks/out/kinect_trajectory.png.

Realism (issue 13): ``--episodes K`` episodes, each with a fresh mounting error of the Kinect drawn
from the config (realistic) or none (ideal); per fix, the position error of the full pipeline and of
the env's fast path. Prints median, p90 and RMSE, realistic vs ideal, and the floor depth noise
against the model's sqrt(sigma_z^2 + q^2 / 12).

    .venv/bin/python benchmarks/kinect_accuracy.py [--height 2.8] [--duration 25] [--seed 0]
    .venv/bin/python benchmarks/kinect_accuracy.py --realism-only --episodes 20
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import cv2
import numpy as np

from parcover_env.config import KinectConfig, MapConfig
from parcover_env.geometry import wrap_angle
from parcover_env.localization.kinect.estimate_model import estimate_fast
from parcover_env.localization.kinect.pipeline import PipelineParams, estimate_poses
from parcover_env.sensors.kinect import KinectSensor, axial_sigma
from parcover_env.viz.kinect_views import trajectory_image
from parcover_env.world.map_model import MapModel

SPEEDS = {"slow (0.015, 0.023)": (0.015, 0.023), "fast (0.08, 0.08)": (0.08, 0.08)}


def run(sensor: KinectSensor, v: float, omega: float, duration: float, rng: np.random.Generator):
    params = PipelineParams(marker_height=sensor.robot_height, robot_radius=sensor.robot_radius)
    dt = 1.0 / sensor.cfg.rate_hz
    n = int(duration / dt)
    cx, cy = sensor.camera.C[:2]
    # An arc of radius v / omega centred on the image centre, symmetric about the image's x axis.
    radius, half = v / omega, 0.5 * omega * n * dt
    centre = np.array([cx - radius * (1 + np.cos(half)) / 2, cy])
    pose = np.array([*(centre + radius * np.array([np.cos(-half), np.sin(-half)])), -half + np.pi / 2])
    true, est = np.empty((n, 3)), np.full((n, 3), np.nan)
    t_render = t_pipe = 0.0
    for k in range(n):
        true[k] = pose
        t0 = time.perf_counter()
        frame = sensor.measure(pose[None], [True], rng, stamp=k * dt)
        t1 = time.perf_counter()
        ests = estimate_poses(frame, sensor.camera, params)
        t2 = time.perf_counter()
        t_render += t1 - t0
        t_pipe += t2 - t1
        if ests:
            est[k] = min(ests, key=lambda e: np.hypot(e.x - pose[0], e.y - pose[1])).pose
        pose = pose + dt * np.array([v * np.cos(pose[2]), v * np.sin(pose[2]), omega])
    ok = ~np.isnan(est[:, 0])
    dxy = est[ok, :2] - true[ok, :2]
    dth = wrap_angle(est[ok, 2] - true[ok, 2])
    z = sensor.camera.C[2] - sensor.robot_height
    mpp = z / sensor.camera.focal
    span = float(np.ptp(sensor.pattern[:, 0]))
    return {
        "true": true, "est": est, "det": ok.mean(),
        "pos_rmse": float(np.sqrt(np.mean(np.sum(dxy ** 2, axis=1)))) if ok.any() else np.nan,
        "head_rmse": float(np.sqrt(np.mean(dth ** 2))) if ok.any() else np.nan,
        "pos_px": float(np.sqrt(np.mean(dxy ** 2)) / mpp) if ok.any() else np.nan,
        "head_px": float(np.sqrt(np.mean(dth ** 2)) * span / mpp) if ok.any() else np.nan,
        "ms_render": 1e3 * t_render / n, "ms_pipe": 1e3 * t_pipe / n,
    }


def floor_noise(height: float, seed: int) -> None:
    """Depth noise on an empty floor (camera looking down) against sqrt(sigma_z^2 + q^2 / 12)."""
    mm = MapModel.from_config(MapConfig(size=(6.0, 6.0)))
    sensor = KinectSensor(KinectConfig(name="floor", position=(3.0, 3.0), height=height), 0.15, 0.3, mm)
    rng = np.random.default_rng(seed)
    clean = sensor.static_depth
    noisy = sensor.lateral_jitter(sensor.noisy_depth(clean, rng), rng)
    ok = noisy > 0
    err = (noisy - clean)[ok]
    z = float(np.median(clean))
    q = z * z / sensor.fb / 8.0
    model = math.sqrt(float(axial_sigma(z)) ** 2 + q * q / 12)
    print(f"floor depth noise at z = {z:.2f} m: std {1e3 * err.std():.2f} mm, model sqrt(sigma_z^2 + q^2/12) "
          f"= {1e3 * model:.2f} mm (sigma_z {1e3 * float(axial_sigma(z)):.2f} mm, q {1e3 * q:.2f} mm): "
          f"ratio {err.std() / model:.2f} (done when in [0.5, 2])")


def realism(height: float, episodes: int, duration: float, seed: int) -> None:
    """Fix errors with per-episode mounting errors (realistic) vs a perfectly mounted Kinect (ideal)."""
    mm = MapModel.from_config(MapConfig(size=(6.0, 6.0)))
    print(f"\nfix error over {episodes} episodes x {duration:.0f} s (Kinect at {height} m, 320x240, fast "
          f"arc), position error in cm")
    print(f"{'model':>10} {'path':>9} {'fixes':>6} {'median':>7} {'p90':>6} {'RMSE':>6}")
    for label, extra in (("realistic", {}), ("ideal", {"mount_tilt_std_deg": 0.0, "mount_yaw_std_deg": 0.0,
                                                      "mount_height_std": 0.0, "lateral_noise_px": 0.0})):
        cfg = KinectConfig(name="bench", position=(3.0, 3.0), height=height, resolution=(320, 240), **extra)
        sensor = KinectSensor(cfg, 0.15, 0.3, mm)
        rng = np.random.default_rng(seed)
        errs: dict[str, list[float]] = {"pipeline": [], "fast": []}
        for _ in range(episodes):
            sensor.mount(rng)
            r = run(sensor, 0.08, 0.08, duration, rng)
            ok = ~np.isnan(r["est"][:, 0])
            errs["pipeline"].extend(np.hypot(*(r["est"][ok, :2] - r["true"][ok, :2]).T).tolist())
            for pose in r["true"]:
                est = estimate_fast(sensor, pose[None], [True], rng)
                errs["fast"].extend(math.hypot(e.x - pose[0], e.y - pose[1]) for e in est)
        for path, e in errs.items():
            e = np.asarray(e)
            print(f"{label:>10} {path:>9} {len(e):6d} {100 * np.median(e):7.2f} {100 * np.percentile(e, 90):6.2f} "
                  f"{100 * np.sqrt(np.mean(e ** 2)):6.2f}")
    print("done when: realistic leader fix RMSE in [0.5, 5] cm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--height", type=float, default=2.8, help="Kinect height (m); robots are 0.3 m tall")
    ap.add_argument("--duration", type=float, default=25.0, help="seconds of driving per run")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "kinect_trajectory.png"))
    ap.add_argument("--episodes", type=int, default=10, help="mounting draws for the realism section")
    ap.add_argument("--episode-duration", type=float, default=5.0, help="seconds of driving per episode")
    ap.add_argument("--realism-only", action="store_true", help="skip the Fig. 10 runs")
    args = ap.parse_args()
    floor_noise(args.height, args.seed)
    realism(args.height, args.episodes, args.episode_duration, args.seed)
    if args.realism_only:
        return
    mm = MapModel.from_config(MapConfig(size=(6.0, 6.0)))
    rng = np.random.default_rng(args.seed)
    plots = []
    print(f"Kinect at {args.height} m looking down, robot r=0.15 m h=0.3 m, 15 Hz, "
          f"{args.duration:.0f} s per run")
    print(f"{'resolution':>10} {'speed':>20} {'pos RMSE mm':>11} {'head RMSE deg':>13} {'detect':>7} "
          f"{'render ms':>9} {'pipe ms':>8} {'pos px':>7} {'head px':>7}")
    for res in ((320, 240), (640, 480)):
        cfg = KinectConfig(name="bench", position=(3.0, 3.0), height=args.height, resolution=res)
        sensor = KinectSensor(cfg, 0.15, 0.3, mm)
        for label, (v, w) in SPEEDS.items():
            r = run(sensor, v, w, args.duration, rng)
            print(f"{res[0]}x{res[1]:<4} {label:>20} {1e3 * r['pos_rmse']:11.2f} "
                  f"{np.degrees(r['head_rmse']):13.2f} {r['det']:7.1%} {r['ms_render']:9.2f} "
                  f"{r['ms_pipe']:8.2f} {r['pos_px']:7.3f} {r['head_px']:7.3f}")
            if res == (640, 480):
                title = f"{label} m/s, rad/s: pos RMSE {1e3 * r['pos_rmse']:.1f} mm, detected {r['det']:.0%}"
                plots.append(trajectory_image(r["true"][:, :2], r["est"][:, :2], title, size=(560, 480)))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out), cv2.cvtColor(np.concatenate(plots, axis=1), cv2.COLOR_RGB2BGR))
    print(f"plot: {out}")
    print("pos px / head px: per-axis position and heading errors in pixels at the robot's depth — the "
          "FastNoise(pos_px, heading_px) of the fast path")


if __name__ == "__main__":
    main()
