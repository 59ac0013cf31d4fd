"""Pinned sonar scans and what the localizer made of them (``pinned_scans.json``), shared by the test
``test_localizer_pinned.py`` and by ``python tests/localization/sonar/pinned_scans.py``, which wrote the
fixture with the localizer as it was before it was compiled (issue 40), and can rewrite it.

Two kinds of cases, every prior from an estimate and its covariance (never the truth):

* ``trial``: the oracle-free benchmark's trials (``benchmarks/sonar_localization.py``: a drive steered
  by odometry, the odometry estimate and covariance as prior, a realistic or mismatched sonar scan),
  localized with each row's configuration (the paper's method, each extension, all of them).
* ``service``: scans the env's sonar localization service (``localization/sonar/service.py``) localized during
  seeded episodes (random driving, scan requests), with the team's estimates and covariances and the
  search region's inflation of that moment; the outcome of :meth:`SonarFixes.match`.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import zlib
from pathlib import Path

import numpy as np

FIXTURE = Path(__file__).with_name("pinned_scans.json")
TRIAL_MAPS = ("hallway", "t_room", "generated:1", "generated:4")
SERVICE_RUNS = (("t_room", 0), ("hallway", 1), ("generated:2", 2), ("generated:5", 3))
SCAN = {"observation": {"scan": {"enabled": True}, "pose_source": "odometry"}}


def _benchmark():
    root = Path(__file__).resolve().parents[3]
    sys.path.insert(0, str(root / "benchmarks"))
    import sonar_localization

    return sonar_localization


def trial_inputs(name: str, n: int, seed: int = 0) -> dict:
    """``n`` trials of the benchmark on map ``name``: scans (realistic and mismatched sonar) and priors."""
    import shapely

    from parcover_env.expert.config import expert_config
    from parcover_env.localization.sonar.config import sonar_localizer_config
    from parcover_env.localization.sonar.known_map import known_map_features
    from parcover_env.scenarios import load_scenario
    from parcover_env.sensors.sonar import SonarRing
    from parcover_env.world.map_model import MapModel

    bench = _benchmark()
    sc = load_scenario(name)
    sonar = sc.robot.sonar
    _, _, sectors = known_map_features(sc.map, sonar.range_max, expert_config(sc).navigator.sector_rule)
    world = MapModel.from_config(sc.map, include_unknown=True)
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence([seed, zlib.crc32(name.encode())]).spawn(3)]
    goal_region = shapely.union_all([s.polygon for s in sectors if s.features])
    trials, _ = bench.make_trials(sc, world, goal_region, n, streams[0])
    ring, ring_mis = SonarRing(sonar), SonarRing(bench.mismatched(sonar))
    return {"scans": [ring.scan(t.truth, world.segments, None, sc.robot.radius, streams[1]).tolist() for t in trials],
            "scans_mismatch": [ring_mis.scan(t.truth, world.segments, None, sc.robot.radius, streams[2]).tolist()
                               for t in trials],
            "estimates": [t.estimate.tolist() for t in trials],
            "covariances": [t.covariance.tolist() for t in trials],
            "loc": dataclasses.asdict(sonar_localizer_config(sc))}


def rows(loc) -> list[tuple[str, object, bool]]:
    """(label, localizer config, mismatched scan) of each row of ``benchmarks/sonar_localization.py`` (as
    that script defined them when the fixture was written; kept here so the test does not read the script)."""
    import dataclasses

    paper = loc.paper_method()
    return [("paper (Fig. 6 + Fig. 11 filter)", paper, False),
            ("paper without the Fig. 11 filter", dataclasses.replace(paper, filter=False), False),
            ("paper + polish", dataclasses.replace(paper, polish=True), False),
            ("paper + arc fallback", dataclasses.replace(paper, arc_fallback=True), False),
            ("paper + grid fallback", dataclasses.replace(paper, grid_fallback=True), False),
            ("all extensions (default)", loc, False),
            ("paper, sonar mismatch", paper, True),
            ("all extensions, sonar mismatch", loc, True)]


def localize_trial(name: str, inputs: dict, k: int, params, mismatch: bool):
    """The localizer's result on trial ``k`` of ``inputs`` (as the benchmark calls it)."""
    from parcover_env.expert.config import expert_config
    from parcover_env.localization.sonar.known_map import known_map_features
    from parcover_env.localization.sonar.localizer import localize
    from parcover_env.scenarios import load_scenario
    from parcover_env.sensors.sonar import SonarRing

    sc = load_scenario(name)
    known, feats, sectors = known_map_features(sc.map, sc.robot.sonar.range_max,
                                               expert_config(sc).navigator.sector_rule)
    est, cov = np.array(inputs["estimates"][k]), np.array(inputs["covariances"][k])
    scan = np.array(inputs["scans_mismatch" if mismatch else "scans"][k])
    return localize(scan, SonarRing(sc.robot.sonar).scan_angles, known, sectors, (est[:2], cov[:2, :2]), params,
                    sonar=sc.robot.sonar, features=feats, heading=float(est[2]))


def service(name: str, n_robots: int):
    """The env's scan service of scenario ``name`` (scans enabled), outside an env."""
    from parcover_env.localization.sonar.service import SonarFixes
    from parcover_env.scenarios import load_scenario
    from parcover_env.world.map_model import MapModel

    sc = load_scenario(name, SCAN)
    return SonarFixes(sc, MapModel.from_config(sc.map).segments, n_robots)


def service_cases(name: str, seed: int, steps: int = 300) -> list[dict]:
    """Every scan the service localizes in a seeded episode of ``name``: random driving (seeded), each
    robot asking for a scan every so often; the inputs and outcome of each :meth:`SonarFixes.match`."""
    import parcover_env

    env = parcover_env.parallel_env(name, overrides=SCAN)
    env.reset(seed=seed)
    svc = env.scanner
    cases: list[dict] = []
    orig = svc.match

    def spy(i, ranges, request, inflation):
        pose, informative = orig(i, ranges, request, inflation)
        cases.append({"i": int(i), "ranges": np.asarray(ranges).tolist(), "estimate": request.estimate.tolist(),
                      "covariance": None if request.covariance is None else request.covariance.tolist(),
                      "inflation": float(inflation), "pose": None if pose is None else pose.tolist(),
                      "informative": bool(informative)})
        return pose, informative

    svc.match = spy
    rng = np.random.default_rng(seed)
    for step in range(steps):
        if not env.agents:
            break
        if step % 100 == 50:  # a drifted estimate (wrong by more than its covariance says): rejections, widening
            true = env.true_poses()[0]
            env.estimator.fix(0, true + np.array([0.5, -0.4, 0.08]), np.diag([0.05**2, 0.05**2, 0.02**2]))
        acts = {}
        for k, a in enumerate(env.agents):
            scan = 1.0 if (step + 11 * k) % 30 == 29 else -1.0
            acts[a] = np.array([rng.uniform(-0.2, 1.0), rng.uniform(-1, 1), scan], np.float32)
        env.step(acts)
    return cases


def result_row(res) -> dict:
    return {"success": bool(res.success), "pose": None if res.pose is None else res.pose.tolist(),
            "error": float(res.error), "feature": int(res.feature), "candidates": int(res.candidates_tried)}


def build(trials: int = 10, with_trials: bool = True) -> dict:
    from parcover_env.localization.sonar.config import SonarLocalizerConfig

    out: dict = {"trial": {}, "service": {}}
    for name in TRIAL_MAPS if with_trials else ():
        inputs = trial_inputs(name, trials)
        loc = SonarLocalizerConfig(**inputs["loc"])
        rows = {}
        for label, params, mis in rows(loc):
            rows[label] = [result_row(localize_trial(name, inputs, k, params, mis)) for k in range(trials)]
        out["trial"][name] = {"inputs": inputs, "rows": rows}
    for name, seed in SERVICE_RUNS:
        out["service"][f"{name}@{seed}"] = service_cases(name, seed)
    return out


if __name__ == "__main__":
    data = build(with_trials="--service-only" not in sys.argv)
    if len(sys.argv) > 1 and sys.argv[1] == "--service-only":  # keep the trial cases, redo the service ones
        data["trial"] = json.loads(FIXTURE.read_text())["trial"]
    FIXTURE.write_text(json.dumps(data, separators=(",", ":")))
    n_trial = sum(len(v["rows"]) * len(v["inputs"]["scans"]) for v in data["trial"].values())
    n_service = sum(len(v) for v in data["service"].values())
    print(f"wrote {FIXTURE}: {n_trial} trial localizations, {n_service} service scans")
