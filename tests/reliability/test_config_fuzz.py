"""Config fuzzing: mutated scenario files either load (scenario + env + reset + steps) or raise the
package's ConfigError naming the file and the key; nothing else. CI runs a few hundred hypothesis
cases; ``docs/lab/scripts/fuzz_report.py --cases 1000`` is the long run."""

from __future__ import annotations

import itertools
import tempfile
from pathlib import Path

import pytest
import yaml
from config_mutations import apply_mutations, base_mapping, cases_strategy, check_file
from hypothesis import HealthCheck, given, settings

import parcover_env as pe
from parcover_env.errors import ConfigError

_TMP = Path(tempfile.mkdtemp(prefix="parcover_cfg_fuzz_"))
_COUNTER = itertools.count()


def _write(text: str) -> Path:
    path = _TMP / f"case_{next(_COUNTER):05d}.yaml"
    path.write_text(text)
    return path


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(cases_strategy(max_mutations=2))
def test_mutated_scenarios_load_or_raise_config_error(case):
    name, mutations = case
    path = _write(apply_mutations(base_mapping(name), mutations))
    outcome, detail = check_file(path)
    assert outcome != "FAIL", f"[{name}] {mutations!r}: {detail}"


def _mutated(name: str, edit) -> Path:
    data = base_mapping(name)
    edit(data)
    return _write(yaml.safe_dump(data, sort_keys=False))


def _set(path: tuple, value):
    def edit(d):
        node = d
        for k in path[:-1]:
            node = node.setdefault(k, {}) if isinstance(k, str) else node[k]
        node[path[-1]] = value
    return edit


def _drop(key):
    return lambda d: d.pop(key)


# (base, edit, expected dotted key prefix) — each issue category with the key the error must name
CASES = {
    "dropped start": ("office", _drop("start"), "start"),
    "dropped map": ("t_room", _drop("map"), "map"),
    "wrong type radius": ("office", _set(("robot", "radius"), "big"), "robot.radius"),
    "bool as number": ("office", _set(("kpoi_radius",), True), "kpoi_radius"),
    "nan speed": ("office", _set(("robot", "max_speed"), float("nan")), "robot.max_speed"),
    "negative radius": ("hallway", _set(("robot", "radius"), -0.1), "robot.radius"),
    "zero robots": ("office", _set(("n_robots",), 0), "n_robots"),
    "too many robots for the start": ("t_room", _set(("n_robots",), 12), "n_robots"),
    "self-intersecting obstacle": ("office", _set(("map", "obstacles"), [[[1, 1], [2, 2], [2, 1], [1, 2]]]),
                                   "map.obstacles[0]"),
    "degenerate obstacle": ("office", _set(("map", "obstacles"), [[[1, 1], [2, 1], [3, 1]]]),
                            "map.obstacles[0]"),
    "two-vertex boundary": ("t_room", _set(("map", "boundary"), [[0, 0], [4, 4]]), "map.boundary"),
    "zero-length wall": ("tree", lambda d: d["map"].setdefault("walls", []).append([[5, 5], [5, 5]]),
                         "map.walls[0]"),
    "kpoi in obstacle": ("office", lambda d: d["kpois"].__setitem__(1, [2.0, 2.5]), "kpois[1]"),
    "kpoi outside map": ("office", lambda d: d["kpois"].__setitem__(0, [-1.0, 2.0]), "kpois[0]"),
    "duplicate kpoi": ("tree", lambda d: d["kpois"].append(list(d["kpois"][3])), "kpois[15]"),
    "no kpois": ("office", _set(("kpois",), []), "kpois"),
    "start in wall": ("office", _set(("start",), {"x": 2.0, "y": 2.5}), "start"),
    "kinect at the ceiling": ("office", lambda d: d["kinects"][0].update(pitch_deg=-30),
                              "kinects[0].pitch_deg"),
    "kinect at the horizon": ("tree", lambda d: d["kinects"][2].update(pitch_deg=15), "kinects[2].pitch_deg"),
    "kinect below robots": ("office", lambda d: d["kinects"][0].update(height=0.2), "kinects[0].height"),
    "unknown key typo": ("office", _set(("robot", "radiu"), 0.1), "robot.radiu"),
    "oversized map": ("office", _set(("map", "size"), [2000, 2000]), "map.size"),
    "tunnelling speed": ("office", lambda d: (_set(("robot", "max_speed"), 5.0)(d),
                                             _set(("robot", "drive", "wheel_speed_max"), 5.0)(d)), "physics.dt"),
    "wheels slower than max_speed": ("office", _set(("robot", "max_speed"), 5.0), "robot.drive.wheel_speed_max"),
    "zero drive lag": ("tree", _set(("robot", "drive", "tau"), 0.0), "robot.drive.tau"),
    "negative odometry noise": ("hallway", _set(("robot", "odometry", "scale_std"), -0.01),
                                "robot.odometry.scale_std"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_category_names_file_and_key(case):
    base, edit, key = CASES[case]
    path = _mutated(base, edit)
    with pytest.raises(ConfigError) as info:
        pe.load_scenario(path) if key != "n_robots" or base != "t_room" else pe.parallel_env(path)
    assert info.value.source == str(path)
    assert info.value.key.startswith(key), (info.value.key, key)
    assert str(path) in str(info.value) and info.value.key in str(info.value)


@pytest.mark.parametrize("text, key", [
    ("name: x\nmap: {size: [1, 1]\n", "line"),     # unclosed flow mapping
    ("- 1\n- 2\n", "<top level>"),
    ("", "<top level>"),
    ("\x00\x01binary", "line"),
])
def test_unparseable_files(text, key):
    path = _write(text)
    with pytest.raises(ConfigError) as info:
        pe.load_scenario(path)
    assert info.value.source == str(path) and info.value.key.startswith(key)


def test_oracle_detects_a_foreign_exception(monkeypatch):
    """The oracle itself can fail: an exception other than ConfigError is reported as FAIL."""
    path = _write(apply_mutations(base_mapping("t_room"), []))
    assert check_file(path)[0] == "loaded"

    def boom(*args, **kwargs):
        raise KeyError("boom")

    monkeypatch.setattr(pe, "parallel_env", boom)
    assert check_file(path)[0] == "FAIL"


# ------------------------------------------------------------------------------------------------
# Formerly found bugs, now guarded in config.py.

def test_huge_map_is_refused_at_load():
    path = _mutated("office", _set(("map", "size"), [1000.0, 1000.0]))
    with pytest.raises(ConfigError) as info:
        pe.load_scenario(path)
    assert info.value.key.startswith(("map.size", "planner.resolution"))


def test_boundary_outside_size_is_refused():
    path = _mutated("t_room", _set(("map", "boundary"), [[0, 0], [1e6, 0], [1e6, 1e6], [0, 1e6]]))
    with pytest.raises(ConfigError) as info:
        pe.load_scenario(path)
    assert info.value.key.startswith("map.boundary")
