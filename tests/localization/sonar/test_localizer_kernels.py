"""The compiled sonar localizer (``localizer_kernels.py``, ``scan_kernels.py``) against the numpy/scipy code it
replaced (``tests/references/sonar_localizer.py``): the same values bit for bit, on hand-built cases
with known answers and on the pinned scans (``pinned_scans.json``)."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[2]))
import pinned_scans as pinned  # noqa: E402
from references import sonar_localizer as ref  # noqa: E402

from parcover_env.geometry import numpy_order  # noqa: E402
from parcover_env.localization.sonar import localizer as loc  # noqa: E402
from parcover_env.localization.sonar import localizer_kernels as kern  # noqa: E402
from parcover_env.localization.sonar.config import SonarLocalizerConfig  # noqa: E402
from parcover_env.localization.sonar.features import characteristic_points, map_features  # noqa: E402
from parcover_env.localization.sonar.filter import filter_scan  # noqa: E402
from parcover_env.localization.sonar.localizer import (  # noqa: E402
    Ellipse,
    arc_candidates,
    pose_candidates,
    scan_error,
)
from parcover_env.world.map_model import MapModel  # noqa: E402

DATA = json.loads(pinned.FIXTURE.read_text())
ANGLES = np.radians(np.arange(72) * 5.0)


def _pinned_scans(extra: int = 150) -> list[np.ndarray]:
    scans = [np.array(s) for m in DATA["trial"].values() for key in ("scans", "scans_mismatch")
             for s in m["inputs"][key]]
    scans += [np.array(c["ranges"]) for cs in DATA["service"].values() for c in cs]
    g = np.random.default_rng(0)
    for _ in range(extra):  # and noisier copies of them
        s = scans[g.integers(len(scans))]
        scans.append(np.minimum(s + g.normal(0, 0.05, 72) * (g.uniform(size=72) < 0.3), 2.54))
    return scans


def test_mean_of_sums_like_numpy():
    g = np.random.default_rng(1)
    for n in [*range(1, 300), 511, 512, 513, 1000, numpy_order.MAX_SUM]:
        x = g.normal(size=n) * 10.0 ** g.integers(-3, 3, n)
        assert numpy_order.mean_of(x, n) == x.mean(), n
    assert numpy_order.mean_of(np.array([0.5, 0.25, 0.0]), 3) == 0.25


def test_scan_error_by_hand_and_as_the_sorted_numpy_mean():
    measured = np.array([1.0, 1.0, 1.0, 1.0])
    synth = np.array([[1.25, 0.75, 3.0, 1.0], [1.0, 1.0, 1.0, 1.0]])
    # errors 0.25, 0.25, 0.5 (clipped from 2), 0: all -> 0.25; the worst quarter dropped -> 1/6
    assert scan_error(measured, synth, 0.5).tolist() == [0.25, 0.0]
    assert scan_error(measured, synth, 0.5, trim=0.25).tolist() == [pytest.approx(0.5 / 3, abs=1e-15), 0.0]
    g = np.random.default_rng(2)
    for trim in (0.0, 0.1, 0.3):
        meas = np.round(g.uniform(0.1, 2.54, 72), 2)
        syn = meas + g.normal(0, 0.3, (50, 72)) * (g.uniform(size=(50, 72)) < 0.7)
        keep = 72 - math.floor(trim * 72)
        e = np.sort(np.minimum(np.abs(syn - meas), 0.5), axis=1)[:, :keep] if keep < 72 else \
            np.minimum(np.abs(syn - meas), 0.5)
        np.testing.assert_array_equal(scan_error(meas, syn, 0.5, trim), e.mean(axis=1))
        x = np.minimum(np.abs(syn - meas), 0.5)
        if keep == 72 or np.array_equal(np.partition(x, keep - 1, axis=1), np.sort(x, axis=1)):
            # numpy's partition of a short row sorts it (AVX-512): the numpy code gave these very bits
            np.testing.assert_array_equal(scan_error(meas, syn, 0.5, trim), ref.scan_error(meas, syn, 0.5, trim))
    with pytest.raises(ValueError, match="do not match"):
        scan_error(np.ones(4), np.ones((2, 5)), 0.5)


def test_ellipse_distance_equals_the_numpy_formula_and_is_exact_by_hand():
    circle = Ellipse((1.0, 2.0), (1.0, 1.0))
    assert circle.distance([[4.0, 2.0], [1.0, 2.5], [1.0, 2.0]]).tolist() == [2.0, 0.0, 0.0]
    g = np.random.default_rng(3)
    for _ in range(200):
        e = Ellipse(tuple(g.uniform(-3, 3, 2)), tuple(g.uniform(0, 1.5, 2)), float(g.uniform(-3, 3)))
        pts = np.asarray(e.center) + g.normal(0, 1.5, (40, 2))
        got = e.distance(pts)
        np.testing.assert_array_equal(got, ref.ellipse_distance(e, pts))
        rec = e.kernel_record()
        for (x, y), d in zip(pts, got, strict=True):
            if kern.ellipse_beyond(x, y, rec, 0.3):  # the shortcut never drops a point nearer than reach
                assert d >= 0.3


def test_free_status_agrees_with_shapely_and_leaves_the_boundary_undecided():
    import parcover_env

    m = MapModel.from_config(parcover_env.load_scenario("t_room").map, include_unknown=False)
    segs = np.ascontiguousarray(m.segments)
    x0, y0, x1, y1 = m.free.bounds
    g = np.random.default_rng(4)
    pts = g.uniform((x0 - 0.5, y0 - 0.5), (x1 + 0.5, y1 + 0.5), (3000, 2))
    got = np.array([kern.free_status(x, y, segs) for x, y in pts])
    assert set(got.tolist()) <= {0, 1} and 0 < got.sum() < len(got)
    np.testing.assert_array_equal(got == 1, shapely.contains_xy(m.free, pts[:, 0], pts[:, 1]))
    a = segs[0]
    mid = 0.5 * (a[:2] + a[2:])
    assert kern.free_status(mid[0], mid[1], segs) == -1
    assert kern.free_status(mid[0] + 5e-10, mid[1], segs) == -1


def test_argsort_table_orders_ties_as_numpy():
    table = numpy_order.argsort4_table()
    g = np.random.default_rng(5)
    for _ in range(500):
        f = g.integers(0, 3, 4).astype(float) * 0.25
        sim = np.arange(12.0).reshape(4, 3)
        ind = np.argsort(f)
        kern.order_simplex(sim, f.copy(), table)
        np.testing.assert_array_equal(sim, np.arange(12.0).reshape(4, 3)[ind])


def test_scan_features_and_filter_equal_the_numpy_code_on_pinned_scans():
    params = [SonarLocalizerConfig(), SonarLocalizerConfig(window=3, plateau_tol=0.05, prominence=0.0)]
    for s in _pinned_scans():
        for p in params:
            a, b = characteristic_points(s, ANGLES, 2.54, p), ref.characteristic_points(s, ANGLES, 2.54, p)
            assert (a.labels, a.corners, a.walls) == (b.labels, b.corners, b.walls)
            np.testing.assert_array_equal(a.maxima, b.maxima)
            np.testing.assert_array_equal(a.minima, b.minima)
        for args in ((4, 1, 0.03), (6, 2, 0.05)):
            np.testing.assert_array_equal(filter_scan(s, ANGLES, 2.54, *args), ref.filter_scan(s, ANGLES, 2.54, *args))


def test_pose_and_arc_candidates_equal_the_numpy_code():
    import parcover_env

    sc = parcover_env.load_scenario("t_room")
    feats = map_features(MapModel.from_config(sc.map, include_unknown=False))
    p = SonarLocalizerConfig()
    region = Ellipse((2.0, 2.0), (1.5, 1.0), 0.3).polygon().buffer(0.3)
    n = 0
    for s in _pinned_scans(extra=0)[::7]:
        scan = characteristic_points(s, ANGLES, 2.54, p)
        for f in feats:
            got, want = pose_candidates(f, scan, p), ref.pose_candidates(f, scan, p)
            np.testing.assert_array_equal(np.reshape(got, (-1, 3)), np.reshape(want, (-1, 3)))
            got, want = arc_candidates(f, scan, region), ref.arc_candidates(f, scan, region)
            np.testing.assert_array_equal(np.reshape(got, (-1, 3)), np.reshape(want, (-1, 3)))
            n += len(got)
    assert n > 100


def test_polish_equals_scipys_nelder_mead_also_next_to_a_wall():
    """The compiled Nelder-Mead takes scipy's steps; a pose within 1e-9 m of a wall goes through scipy."""
    import parcover_env

    sc = parcover_env.load_scenario("t_room")
    known = MapModel.from_config(sc.map, include_unknown=False)
    inputs = DATA["trial"]["t_room"]["inputs"]
    p = SonarLocalizerConfig(**inputs["loc"])
    for k in range(4):
        est, cov = np.array(inputs["estimates"][k]), np.array(inputs["covariances"][k])
        ell = Ellipse.from_covariance(est[:2], cov[:2, :2] + 0.01 * np.eye(2), p.covariance_sigmas)
        r = np.array(inputs["scans"][k])
        for start in (est, est + np.array([0.04, -0.03, 0.02])):
            got = loc._polish(start.copy(), r, ANGLES, known, ell, p, sc.robot.sonar)
            want = _scipy_polish(start.copy(), r, known, ell, p, sc.robot.sonar)
            assert got[1] == want[1] and np.array_equal(got[0], want[0])
    # next to a wall: the first simplex vertex lies on it, undecided for the compiled test
    a = known.segments[0]
    on_wall = np.array([0.5 * (a[0] + a[2]), 0.5 * (a[1] + a[3]), 0.1])
    ell = Ellipse(tuple(on_wall[:2]), (0.3, 0.3))
    r = np.array(inputs["scans"][0])
    rec = ell.kernel_record()
    from parcover_env.geometry.rays import disc_planes
    from parcover_env.sensors.sonar import beam_kernel_arguments
    from parcover_env.sensors.sonar_kernels import Discs

    walls, offsets, share, rules = beam_kernel_arguments(sc.robot.sonar, known.segments, on_wall[2] + ANGLES[None])
    no_discs = Discs(*disc_planes(np.zeros((0, 2)), 0.0, np.full(1, -1), 1))
    fit = kern.ScanFit(measured=r, angles=ANGLES, clip=p.error_clip, keep=65, ell=rec, ecos=kern.EDGE_COS,
                       esin=kern.EDGE_SIN, reach=p.ellipse_distance, free=known.segments, walls=walls, offsets=offsets,
                       share=share, discs=no_discs, rules=rules, rmax=2.54)
    nm = kern.Simplex(0.03, p.polish_iters, 1e-3, 1e-5, numpy_order.argsort4_table())
    *_, undecided = kern.nelder_mead(on_wall, nm, fit)
    assert undecided
    got = loc._polish(on_wall.copy(), r, ANGLES, known, ell, p, sc.robot.sonar)
    want = _scipy_polish(on_wall.copy(), r, known, ell, p, sc.robot.sonar)
    assert got[1] == want[1] and np.array_equal(got[0], want[0])


def _scipy_polish(pose, r, map_model, ellipse, p, sonar):
    from scipy.optimize import minimize

    def cost(x):
        if not map_model.contains(x[None, :2])[0] or ref.ellipse_distance(ellipse, x[None, :2])[0] >= \
                p.ellipse_distance:
            return p.error_clip
        synth = ref.synthetic_scans(x[None], ANGLES, map_model.segments, sonar)
        return float(ref.scan_error(r, synth, p.error_clip, p.error_trim)[0])

    res = minimize(cost, pose, method="Nelder-Mead",
                   options={"maxiter": p.polish_iters, "xatol": 1e-3, "fatol": 1e-5,
                            "initial_simplex": pose + np.array([[0, 0, 0], [0.03, 0, 0], [0, 0.03, 0], [0, 0, 0.03]])})
    return np.asarray(res.x, dtype=float), float(res.fun)


@pytest.mark.parametrize("name", ["t_room", "generated:4"])
def test_localize_equals_the_numpy_code_on_pinned_scans(name):
    """Bit for bit, every benchmark row (the pinned test allows 1e-9 for another BLAS build)."""
    inputs = DATA["trial"][name]["inputs"]
    p0 = SonarLocalizerConfig(**inputs["loc"])
    import parcover_env
    from parcover_env.expert.config import expert_config
    from parcover_env.localization.sonar.known_map import known_map_features
    from parcover_env.sensors.sonar import SonarRing

    sc = parcover_env.load_scenario(name)
    rule = expert_config(sc).navigator.sector_rule
    known, feats, sectors = known_map_features(sc.map, sc.robot.sonar.range_max, rule)
    angles = SonarRing(sc.robot.sonar).scan_angles
    for _, params, mis in pinned.rows(p0):
        for k in range(0, len(inputs["scans"]), 3):
            est, cov = np.array(inputs["estimates"][k]), np.array(inputs["covariances"][k])
            scan = np.array(inputs["scans_mismatch" if mis else "scans"][k])
            args = (scan, angles, known, sectors, (est[:2], cov[:2, :2]), params)
            kw = {"sonar": sc.robot.sonar, "features": feats, "heading": float(est[2])}
            a, b = loc.localize(*args, **kw), ref.localize(*args, **kw)
            assert (a.success, a.error, a.candidates_tried, a.feature) == (b.success, b.error, b.candidates_tried,
                                                                           b.feature)
            assert (a.pose is None and b.pose is None) or np.array_equal(a.pose, b.pose)
