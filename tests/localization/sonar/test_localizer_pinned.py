"""The sonar localizer and the env's scan service keep their outcomes on pinned scans (issue 40).

``pinned_scans.json`` (written by ``pinned_scans.py`` with the localizer as it was before it was
compiled) holds realistic scans with their priors (odometry estimate and covariance, never the truth)
and what came out: per benchmark row (the paper's method, each extension, all of them) whether the
localizer accepted a pose, the pose, its scan error, the feature and how many synthetic scans it
computed; per service scan the pose :meth:`SonarFixes.match` returned (None: rejected) and whether
the scan was informative.

Tolerance: outcomes, features and counts must be equal; poses and errors within 1e-9 (m, rad). On
the machine that wrote the fixture they are bit-identical (the compiled path does the same float
operations in the same order, LAPACK/BLAS included); the slack only allows another BLAS/LAPACK build
to differ in the last bits.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
import pinned_scans as pinned  # noqa: E402

from parcover_env.localization.estimator import FixRequest  # noqa: E402
from parcover_env.localization.sonar.config import SonarLocalizerConfig  # noqa: E402

DATA = json.loads(pinned.FIXTURE.read_text())
TOL = 1e-9


def _same_pose(got, want) -> bool:
    if got is None or want is None:
        return got is None and want is None
    return bool(np.allclose(got, want, rtol=0.0, atol=TOL))


@pytest.mark.parametrize("name", sorted(DATA["trial"]))
def test_localizer_outcomes_on_pinned_benchmark_scans(name):
    case = DATA["trial"][name]
    inputs = case["inputs"]
    loc = SonarLocalizerConfig(**inputs["loc"])
    rows = {label: (params, mis) for label, params, mis in pinned.rows(loc)}
    assert set(rows) == set(case["rows"])
    n = len(inputs["scans"])
    for label, want_rows in case["rows"].items():
        params, mis = rows[label]
        for k in range(n):
            want = want_rows[k]
            got = pinned.result_row(pinned.localize_trial(name, inputs, k, params, mis))
            where = f"{name} / {label} / trial {k}"
            assert (got["success"], got["feature"], got["candidates"]) == (
                want["success"], want["feature"], want["candidates"]), where
            assert _same_pose(got["pose"], want["pose"]), where
            assert got["error"] == pytest.approx(want["error"], abs=TOL, rel=0.0), where


@pytest.mark.parametrize("run", sorted(DATA["service"]))
def test_scan_service_outcomes_on_pinned_episode_scans(run):
    name = run.split("@")[0]
    cases = DATA["service"][run]
    assert cases, "the episode localized no scan"
    svc = pinned.service(name, len(cases[0]["estimate"]))
    for k, c in enumerate(cases):
        est = np.array(c["estimate"])
        cov = None if c["covariance"] is None else np.array(c["covariance"])
        request = FixRequest(0.0, est.copy(), est, np.zeros(len(est), bool), cov)  # the truth is never read
        pose, informative = svc.match(c["i"], np.array(c["ranges"]), request, c["inflation"])
        assert informative == c["informative"], f"{run} scan {k}"
        assert _same_pose(pose, c["pose"]), f"{run} scan {k}: {pose} vs {c['pose']}"


def test_the_pinned_scans_cover_every_outcome():
    """The fixture is not all successes: rejections, uninformative scans and widened regions occur."""
    trial = [r["success"] for case in DATA["trial"].values() for rows in case["rows"].values() for r in rows]
    service = [c for cases in DATA["service"].values() for c in cases]
    assert 0 < sum(trial) < len(trial)
    assert any(c["pose"] is None and c["informative"] for c in service)  # rejected
    assert any(not c["informative"] for c in service)  # uninformative
    assert any(c["pose"] is not None for c in service)  # accepted or held
    assert any(c["inflation"] > 1 for c in service)
