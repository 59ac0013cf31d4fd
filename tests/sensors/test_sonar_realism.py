"""Realistic sonar physics on hand-built walls: incidence limit, corners, multipath, cross-talk, dropouts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import SonarConfig
from parcover_env.config.presets import apply_preset
from parcover_env.scenarios import load_scenario
from parcover_env.sensors.sonar import SonarRing, crosstalk, simulate_beams

QUIET = {"noise_std": 0.0, "noise_rel": 0.0, "quantization": 0.0}


def _one_beam(cfg: SonarConfig, origin, axis_deg: float, segments) -> float:
    return float(simulate_beams(cfg, np.array([origin], dtype=float), np.array([[math.radians(axis_deg)]]),
                                np.asarray(segments, dtype=float), np.zeros((0, 2)), 0.0, np.array([-1]))[0, 0])


@pytest.mark.parametrize("incidence, echo", [(0.0, True), (15.0, True), (19.0, True), (23.0, False), (40.0, False)])
def test_wall_echoes_only_within_the_incidence_limit(incidence, echo):
    cfg = SonarConfig(cone_deg=2.0, incidence_max_deg=20.0, multipath=False, **QUIET)
    wall = [[1.0, -5.0, 1.0, 5.0]]  # x = 1, normal along +x
    r = _one_beam(cfg, (0.0, 0.0), incidence, wall)
    if echo:  # the nearest echoing sub-ray of the 2-degree cone: the one closest to the normal
        near = max(incidence - 1.0, 0.0)
        assert r == pytest.approx(1.0 / math.cos(math.radians(near)), abs=1e-9)
    else:
        assert r == cfg.range_max
    ray = SonarConfig(model="ray", **QUIET)  # the ideal ray sees any wall
    assert _one_beam(ray, (0.0, 0.0), incidence, wall) == pytest.approx(1.0 / math.cos(math.radians(incidence)))


def test_concave_corner_retro_reflects_at_the_corner_range():
    cfg = SonarConfig(**QUIET)  # realistic default: cone 30 deg, incidence 20 deg, multipath
    corner = [[0.0, 0.0, 3.0, 0.0], [0.0, 0.0, 0.0, 3.0]]  # walls meet at (0, 0)
    r = _one_beam(cfg, (1.0, 1.0), 225.0, corner)  # beam into the corner, 45 deg off both walls
    assert r == pytest.approx(math.sqrt(2.0), abs=1e-9)
    # seen from outside the wedge the vertex is convex: no retro-reflection
    assert _one_beam(cfg, (-1.0, -1.0), 45.0, corner) == cfg.range_max


def test_multipath_reads_the_two_bounce_length():
    # beam along +x meets the 45-degree wall y = x - 1 at (1, 0), is mirrored to +y and meets the
    # wall y = 0.8 head-on: the echo retraces the path and reads 1 + 0.8
    walls = [[0.5, -0.5, 1.5, 0.5], [0.6, 0.8, 1.6, 0.8]]
    cfg = SonarConfig(cone_deg=1.0, **QUIET)
    assert _one_beam(cfg, (0.0, 0.0), 0.0, walls) == pytest.approx(1.8, abs=2e-3)
    lost = SonarConfig(cone_deg=1.0, multipath=False, **QUIET)
    assert _one_beam(lost, (0.0, 0.0), 0.0, walls) == lost.range_max
    # the second wall out of range after the bounce: lost as well
    short = SonarConfig(cone_deg=1.0, range_max=1.7, **QUIET)
    assert _one_beam(short, (0.0, 0.0), 0.0, walls) == short.range_max


def test_crosstalk_from_a_robot_whose_ring_faces_the_sensor():
    cfg = SonarConfig(layout="amigobot", crosstalk_prob=1.0, **QUIET)
    ring = SonarRing(cfg)
    facing = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, math.pi]])  # beams at +-12 deg see each other
    x = crosstalk(cfg, facing, ring.beam_angles, np.zeros((0, 4)))
    assert x[0, 2] == pytest.approx(1.0) and x[0, 3] == pytest.approx(1.0)  # d / 2
    assert np.all(np.isinf(x[0, [0, 1, 4, 5, 6, 7]]))
    r = ring.measure(facing, np.zeros((0, 4)), 0.2, np.random.default_rng(0))
    assert r[0, 2] == pytest.approx(1.0, abs=1e-6)  # not the robot's own echo at 2 - 0.2
    no_xt = SonarRing(SonarConfig(layout="amigobot", crosstalk_prob=0.0, **QUIET))
    assert no_xt.measure(facing, np.zeros((0, 4)), 0.2, np.random.default_rng(0))[0, 2] == pytest.approx(
        1.8 / math.cos(math.radians(12)) - 0.0, rel=0.1)
    # the other robot turned away (no beam of its ring within 15 deg of the sensor): no cross-talk
    away = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    assert np.all(np.isinf(crosstalk(cfg, away, ring.beam_angles, np.zeros((0, 4)))[0]))
    # a wall between them blocks the ping
    wall = np.array([[1.0, -1.0, 1.0, 1.0]])
    assert np.all(np.isinf(crosstalk(cfg, facing, ring.beam_angles, wall)))


def test_echo_below_range_min_is_lost_or_clipped():
    wall = [[0.1, -1.0, 0.1, 1.0]]
    for below_min, want in (("drop", 2.54), ("clip", 0.15)):
        ring = SonarRing(SonarConfig(n_beams=4, range_min=0.15, below_min=below_min, **QUIET))
        assert ring.measure([[0.0, 0.0, 0.0]], wall, 0.05, None)[0, 0] == pytest.approx(want)


def test_presets_realistic_default_and_ideal_sensors():
    office = load_scenario("office").robot.sonar
    assert (office.model, office.multipath, office.below_min) == ("specular", True, "drop")
    assert office.crosstalk_prob > 0
    ideal = load_scenario("office", preset="ideal")
    assert (ideal.robot.sonar.model, ideal.robot.sonar.multipath, ideal.robot.sonar.crosstalk_prob,
            ideal.robot.sonar.below_min) == ("ray", False, 0.0, "clip")
    k = ideal.kinects[0]
    assert (k.mount_tilt_std_deg, k.mount_yaw_std_deg, k.mount_height_std, k.lateral_noise_px) == (0, 0, 0, 0)
    assert load_scenario("office").kinects[0].mount_tilt_std_deg > 0
    # a scenario naming its sonar model keeps it under ideal (the pinned hallway rollouts)
    assert load_scenario("hallway", preset="ideal").robot.sonar.model == "specular"
    assert apply_preset({"robot": "oops"}, "ideal")["robot"] == "oops"  # malformed: left to the schema
