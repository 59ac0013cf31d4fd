"""Scenario loading: shipped scenarios, overrides, and one clear error per malformed config."""

from __future__ import annotations

import pytest
import yaml

from parcover_env.config import Scenario, scenario_to_yaml
from parcover_env.errors import ConfigError
from parcover_env.scenarios import load_scenario, scenario_names

SHIPPED = ["hallway", "office", "t_room", "tree"]


def test_shipped_scenarios_load():
    assert set(SHIPPED) <= set(scenario_names())
    for name in SHIPPED:
        s = load_scenario(name)
        assert isinstance(s, Scenario) and s.name == name
        assert s.source.endswith(f"{name}.yaml")


def test_office_matches_seed_a_fig11():
    s = load_scenario("office")
    assert s.map.size == (3.2, 4.6)
    assert len(s.kpois) == 2 and s.n_robots == 2 and len(s.kinects) == 1
    (x1, y1), (x2, y2) = s.kpois
    assert x1 < 1.0 and y1 > 3.6  # upper-left corner
    assert x2 > 2.2 and y2 < 1.0  # lower-right corner


def test_configs_are_frozen():
    s = load_scenario("office")
    with pytest.raises(AttributeError):
        s.kpoi_radius = 1.0  # type: ignore[misc]


def test_overrides_merge_and_validate():
    s = load_scenario("office", {"n_robots": 3, "robot": {"max_speed": 0.25}})
    assert s.n_robots == 3 and s.robot.max_speed == 0.25 and s.robot.radius == 0.12


def test_yaml_round_trip(tmp_path):
    s = load_scenario("tree")
    path = tmp_path / "copy.yaml"
    path.write_text(scenario_to_yaml(s))
    assert load_scenario(path) == s


# (description, overrides on office.yaml, expected key in the message, expected words)
BAD = [
    ("typo top-level key", {"kpoi_radiuss": 0.2}, "kpoi_radiuss", "did you mean 'kpoi_radius'"),
    ("typo nested key", {"robot": {"max_sped": 0.2}}, "robot.max_sped", "did you mean 'max_speed'"),
    ("KPOI inside an obstacle", {"kpois": [[2.0, 2.5], [2.85, 0.35]]}, "kpois[0]", "inside a wall"),
    ("unreachable KPOI", {"map": {"walls": [[[0.0, 1.0], [3.2, 1.0]]]}}, "kpois[1]", "unreachable"),
    ("negative radius", {"robot": {"radius": -0.1}}, "robot.radius", "must be > 0"),
    ("wrong type", {"robot": {"max_speed": "fast"}}, "robot.max_speed", "expected a number"),
    ("start inside a wall", {"start": {"x": 2.0, "y": 2.5}}, "start", "inside a wall"),
    ("KPOI outside the map", {"kpois": [[5.0, 5.0]]}, "kpois[0]", "outside the map"),
    ("self-intersecting boundary", {"map": {"boundary": [[0, 0], [3, 4], [3, 0], [0, 4]]}}, "map.boundary",
     "invalid polygon"),
    ("zero robots", {"n_robots": 0}, "n_robots", "must be in [1, 256]"),
    ("team size not a number", {"n_robots": "many"}, "n_robots", "expected"),
    ("Kinect looking at the ceiling", {"kinects": [{"name": "A", "position": [1.6, 2.3], "pitch_deg": 10}]},
     "kinects[0].pitch_deg", "horizon"),
    ("Kinect far from the map", {"kinects": [{"name": "A", "position": [40.0, 40.0]}]}, "kinects[0]",
     "does not see the map"),
    ("duplicate KPOIs", {"kpois": [[0.35, 4.25], [0.35, 4.25]]}, "kpois[1]", "duplicate"),
    ("KPOIs not a list", {"kpois": 5}, "kpois", "expected a list"),
    ("point with 3 coordinates", {"kpois": [[0.35, 4.25, 1.0]]}, "kpois[0]", "expected a list of 2 items"),
    ("NaN number", {"kpoi_radius": float("nan")}, "kpoi_radius", "finite"),
    ("physics step too long", {"physics": {"dt": 0.1}, "robot": {"max_speed": 0.9}}, "physics.dt", "tunnelling"),
    ("unknown sonar layout", {"robot": {"sonar": {"layout": "radial"}}}, "robot.sonar.layout", "expected one of"),
    ("zero-length wall", {"map": {"walls": [[[1.0, 1.0], [1.0, 1.0]]]}}, "map.walls[0]", "zero length"),
    ("degenerate obstacle", {"map": {"obstacles": [[[0.5, 0.5], [1.0, 1.0], [1.5, 1.5]]]}}, "map.obstacles[0]",
     "invalid polygon"),
    ("zero drive lag", {"robot": {"drive": {"tau": 0.0}}}, "robot.drive.tau", "must be > 0"),
    ("endless drive lag", {"robot": {"drive": {"tau": 60.0}}}, "robot.drive.tau", "unable to move"),
    ("zero wheel acceleration", {"robot": {"drive": {"accel_max": 0}}}, "robot.drive.accel_max", "must be > 0"),
    ("negative wheel base", {"robot": {"drive": {"wheel_base": -0.2}}}, "robot.drive.wheel_base", "must be > 0"),
    ("wheels slower than max_speed", {"robot": {"drive": {"wheel_speed_max": 0.1}}},
     "robot.drive.wheel_speed_max", "cannot reach max_speed"),
    ("unknown drive model", {"robot": {"drive": {"model": "tank"}}}, "robot.drive.model", "expected one of"),
    ("negative wheel noise", {"robot": {"odometry": {"wheel_variance": -1e-6}}}, "robot.odometry.wheel_variance",
     "noise must be >= 0"),
    ("negative slip", {"robot": {"odometry": {"slip_turn": -0.1}}}, "robot.odometry.slip_turn", "noise must be >= 0"),
    ("uncalibrated wheels", {"robot": {"odometry": {"diameter_ratio_std": 0.5}}},
     "robot.odometry.diameter_ratio_std", "above 10 %"),
    ("negative fix sigma", {"observation": {"fix_sigma_xy": -0.01}}, "observation.fix_sigma_xy", "noise must be >= 0"),
]


@pytest.mark.parametrize("overrides,key,words", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_malformed_config_names_file_and_key(overrides, key, words):
    with pytest.raises(ConfigError) as info:
        load_scenario("office", overrides)
    err = info.value
    assert "office.yaml" in err.source  # schema errors from overrides name "overrides (over ...office.yaml)"
    assert err.key == key
    assert words in str(err)
    assert str(err).startswith(err.source)


def test_missing_required_key(tmp_path):
    data = yaml.safe_load(scenario_to_yaml(load_scenario("office")))
    del data["start"]
    path = tmp_path / "nostart.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"nostart.yaml: start: required key is missing"):
        load_scenario(path)


def test_missing_file_and_unknown_name():
    with pytest.raises(ConfigError, match="scenario file not found"):
        load_scenario("does/not/exist.yaml")
    with pytest.raises(ConfigError, match="did you mean 'office'"):
        load_scenario("offce")


def test_invalid_yaml_names_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("name: x\nmap: {size: [1, 2]\nkpois: [[0.5, 0.5]]\n")
    with pytest.raises(ConfigError, match=r"broken.yaml: line \d+: invalid YAML"):
        load_scenario(path)


def test_top_level_not_a_mapping(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="expected a mapping"):
        load_scenario(path)


def test_expert_section_is_owned_by_the_expert_typed_validated_and_reachable_from_yaml():
    from parcover_env.expert.config import ExpertConfig, NavigatorConfig, SonarFixConfig, expert_config

    s = load_scenario("office", overrides={"expert": {"patience": 3.0, "sonar_fix": {"stale_after": 5.0},
                                                                   "navigator": {"max_axis": 0.3}}})
    cfg = expert_config(s)
    assert cfg.patience == 3.0 and cfg.sonar_fix.stale_after == 5.0 and cfg.navigator.max_axis == 0.3
    assert cfg.leader_speed == ExpertConfig().leader_speed  # keys left out keep their defaults
    assert expert_config(load_scenario("office")) == ExpertConfig()
    # the scenario keeps the section as read (the env never reads it), and stays hashable
    assert s.expert["patience"] == 3.0 and hash(s) == hash(load_scenario("office"))
    with pytest.raises(ConfigError, match="expert: expected a mapping"):
        load_scenario("office", overrides={"expert": 5})
    bad = [({"leader_speed": 1.5}, "expert.leader_speed"), ({"slow_margin": 0.01}, "expert.slow_margin"),
           ({"sonar_fix": {"gate_heading_deg": 120.0}}, "expert.sonar_fix.gate_heading_deg"),
           ({"sonar_fix": {"gate_heading_max_deg": 95.0}}, "expert.sonar_fix.gate_heading_max_deg"),
           ({"sonar_fix": {"gate_heading_deg": 30.0, "gate_heading_max_deg": 20.0}},
            "expert.sonar_fix.gate_heading_max_deg"),
           ({"sonar_fix": {"gate_sigmas": 0.0}}, "expert.sonar_fix.gate_sigmas"),
           ({"sonar_fix": {"confirm_distance": -0.1}}, "expert.sonar_fix.confirm_distance"),
           ({"navigator": {"min_unmasked_share": 0.0}}, "expert.navigator.min_unmasked_share"),
           ({"navigator": {"mask_sigmas": -1.0}}, "expert.navigator.mask_sigmas"),
           ({"navigator": {"initial_axis": 0.5}}, "expert.navigator.initial_axis"),
           ({"navigator": {"max_axs": 0.5}}, "did you mean 'max_axis'")]
    for override, key in bad:
        with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
            expert_config(load_scenario("office", overrides={"expert": override}))
    with pytest.raises(ConfigError, match="stale_after"):
        SonarFixConfig(stale_after=0.0)
    with pytest.raises(ConfigError, match="sector_rule"):
        NavigatorConfig(sector_rule=3)
