"""Scenario-file mutations for config fuzzing (shared by the CI fuzz test and docs/lab/scripts/fuzz_report.py).

A mutation is a plain tuple ``(kind, selector, value)``; ``apply_mutations`` applies a list of them to
the mapping parsed from a shipped scenario YAML and returns the text to write (a mutation may also
corrupt the YAML text itself). Selectors are resolved modulo the number of candidate places, so the
hypothesis strategy does not depend on the base scenario and shrinks well.

``check_file(path)`` is the oracle: a file either loads (``load_scenario`` and the env constructor
succeed, and the env resets and steps) or raises ``ConfigError`` naming the file and a key. Anything
else is returned as a failure.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from hypothesis import strategies as st

from parcover_env.errors import ConfigError
from parcover_env.scenarios import configs_dir

BASES = ("office", "hallway", "t_room", "tree")

RASTER_CELL_LIMIT = 4_000_000
"""Maps whose planner raster exceeds this many cells are not built by the oracle (see ``check_file``)."""

_ODD_VALUES = [None, "", "abc", True, False, 0, -1, 1, 2.5, -3.7, 1e9, -1e9, 1e-12, 10**30,
               float("nan"), float("inf"), float("-inf"), [], {}, [1, 2], [1, 2, 3], [[0, 0], [1, 1]],
               {"x": 1}, "1.5", "auto", [float("nan"), 1.0]]
_NUM_FACTORS = [-1.0, 0.0, 1e-6, 0.5, 2.0, 10.0, 1e3, 1e9]
_BAD_POLYGONS = [
    [[1.0, 1.0], [2.0, 2.0], [2.0, 1.0], [1.0, 2.0]],          # bow tie (self-intersecting)
    [[1.0, 1.0], [2.0, 1.0], [3.0, 1.0]],                       # collinear (zero area)
    [[1.0, 1.0], [1.0, 1.0], [1.0, 1.0]],                       # one point repeated
    [[1.0, 1.0], [2.0, 1.0]],                                   # two vertices
    [[0.0, 0.0], [1e6, 0.0], [1e6, 1e6], [0.0, 1e6]],           # covers everything
    [[-5.0, -5.0], [-4.0, -5.0], [-4.0, -4.0]],                 # outside the map
    [[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [0.5, 1.5], [1.0, 1.0], [0.5, 0.5]],  # spike + repeated closing
]
KINDS = ("drop", "set", "scale", "bad_polygon", "kpoi_in_wall", "duplicate_kpoi", "n_robots",
         "kinect_pitch", "huge_map", "unknown_key", "truncate_text", "top_level", "wall", "no_kpois")


def mutation_strategy() -> st.SearchStrategy:
    """One mutation ``(kind, selector, value)``."""
    sel = st.integers(0, 10_000)
    odd = (st.sampled_from(_ODD_VALUES) | st.floats(allow_nan=True, allow_infinity=True)
           | st.integers(-10**6, 10**6))
    return st.one_of(
        st.tuples(st.just("drop"), sel, st.none()),
        st.tuples(st.just("set"), sel, odd),
        st.tuples(st.just("scale"), sel, st.sampled_from(_NUM_FACTORS)),
        st.tuples(st.just("bad_polygon"), sel, st.sampled_from(range(len(_BAD_POLYGONS)))),
        st.tuples(st.just("kpoi_in_wall"), sel, st.none()),
        st.tuples(st.just("duplicate_kpoi"), sel, st.none()),
        st.tuples(st.just("n_robots"), sel,
                  st.sampled_from([0, -1, 1, 3, 8, 64, 256, 257, 1.5, "auto", "many"])),
        st.tuples(st.just("kinect_pitch"), sel, st.sampled_from([-90.0, -10.0, 0.0, 5.0, 21.5, 25.0, 45.0,
                                                                 90.0, 91.0, 180.0, 270.0])),
        st.tuples(st.just("huge_map"), sel, st.sampled_from([50.0, 200.0, 1000.0, 1001.0, 1e7])),
        st.tuples(st.just("unknown_key"), sel,
                  st.sampled_from(["kpoi", "robots", "radius ", "mapp", "x_deg"])),
        st.tuples(st.just("truncate_text"), sel, st.floats(0.0, 1.0)),
        st.tuples(st.just("top_level"), sel, st.sampled_from([None, 3, "office", [1, 2], "{"])),
        st.tuples(st.just("wall"), sel,
                  st.sampled_from([((1.0, 1.0), (1.0, 1.0)), ((-1.0, 2.0), (50.0, 2.0)),
                                   ((0.0, 0.0), (3.2, 4.6)), ((1.0,), (2.0, 2.0))])),
        st.tuples(st.just("no_kpois"), sel, st.sampled_from([[], None, [[1.0, 1.0, 1.0]], [["a", "b"]]])),
    )


def cases_strategy(max_mutations: int = 3) -> st.SearchStrategy:
    """``(base scenario name, [mutations])``."""
    muts = st.lists(mutation_strategy(), min_size=1, max_size=max_mutations)
    return st.tuples(st.sampled_from(BASES), muts)


def base_mapping(name: str) -> dict:
    path = configs_dir() / f"{name}.yaml"
    return yaml.safe_load(path.read_text())


def _paths(node: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path (tuple of keys / list indices) in a nested mapping, parents before children."""
    out = []
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list):
        items = enumerate(node)
    else:
        return out
    for k, v in items:
        out.append(prefix + (k,))
        out += _paths(v, prefix + (k,))
    return out


def _get(node: Any, path: tuple) -> Any:
    for k in path:
        node = node[k]
    return node


def _set(node: Any, path: tuple, value: Any) -> None:
    _get(node, path[:-1])[path[-1]] = value


def _apply(data: Any, kind: str, sel: int, value: Any) -> Any:
    """Apply one structural mutation to ``data`` (in place where possible); returns the new root."""
    if not isinstance(data, dict):
        return data
    if kind in ("drop", "set", "scale"):
        paths = _paths(data)
        if kind == "scale":
            paths = [p for p in paths if isinstance(_get(data, p), (int, float))
                     and not isinstance(_get(data, p), bool)]
        if not paths:
            return data
        path = paths[sel % len(paths)]
        if kind == "drop":
            del _get(data, path[:-1])[path[-1]]
        elif kind == "set":
            _set(data, path, copy.deepcopy(value))
        else:
            _set(data, path, _get(data, path) * value)
        return data
    m = data.get("map") if isinstance(data.get("map"), dict) else None
    if kind == "bad_polygon" and m is not None:
        poly = copy.deepcopy(_BAD_POLYGONS[value])
        where = ("obstacles", "unknown_obstacles", "boundary")[sel % 3]
        if where == "boundary":
            m["boundary"] = poly
        else:
            lst = m.get(where)
            m[where] = (lst if isinstance(lst, list) else []) + [poly]
    elif kind == "kpoi_in_wall" and m is not None and isinstance(data.get("kpois"), list) and data["kpois"]:
        solids = [o for o in (m.get("obstacles") or []) if isinstance(o, list) and o]
        try:  # an earlier mutation may have mangled the polygon; then aim at the outer wall
            pts = np.asarray(solids[sel % len(solids)], dtype=float) if solids and sel % 2 == 0 else None
        except (TypeError, ValueError):
            pts = None
        if pts is not None and pts.ndim == 2 and pts.shape[1] == 2:
            target = pts.mean(axis=0).tolist()
        else:  # on the outer wall / outside the map
            target = [-0.01 * (sel % 5), 0.0]
        data["kpois"][sel % len(data["kpois"])] = target
    elif kind == "duplicate_kpoi" and isinstance(data.get("kpois"), list) and data["kpois"]:
        data["kpois"].append(copy.deepcopy(data["kpois"][sel % len(data["kpois"])]))
    elif kind == "n_robots":
        data["n_robots"] = value
    elif kind == "kinect_pitch" and isinstance(data.get("kinects"), list) and data["kinects"]:
        kin = data["kinects"][sel % len(data["kinects"])]
        if isinstance(kin, dict):
            kin["pitch_deg"] = value
    elif kind == "huge_map" and m is not None:
        m["size"] = [value, value] if sel % 2 == 0 else [value, 1.0]
    elif kind == "unknown_key":
        paths = [()] + [p for p in _paths(data) if isinstance(_get(data, p), dict)]
        _get(data, paths[sel % len(paths)])[value] = 1
    elif kind == "wall" and m is not None:
        walls = m.get("walls") if isinstance(m.get("walls"), list) else []
        m["walls"] = walls + [[list(p) for p in value]]
    elif kind == "no_kpois":
        data["kpois"] = copy.deepcopy(value)
    elif kind == "top_level":
        return value
    return data


def apply_mutations(base: dict, mutations: list[tuple]) -> str:
    """The YAML text of ``base`` after ``mutations``."""
    data: Any = copy.deepcopy(base)
    cut = None
    for kind, sel, value in mutations:
        if kind == "truncate_text":
            cut = value
        else:
            data = _apply(data, kind, sel, value)
    text = "{\n" if isinstance(data, str) and data == "{" else yaml.safe_dump(data, sort_keys=False)
    if cut is not None:
        text = text[: int(len(text) * cut)]
    return text


def raster_cells(scenario) -> float:
    """Cells of the planner's raster for this scenario's map."""
    w, h = scenario.map.size
    return (w / scenario.planner.resolution) * (h / scenario.planner.resolution)


def check_file(path: Path, steps: int = 2) -> tuple[str, str]:
    """Oracle for one scenario file: ``(outcome, detail)``.

    outcome is ``loaded`` (load + env + reset + ``steps`` steps OK), ``config_error`` (ConfigError
    naming this file and a key), ``huge`` (loaded, but the planner raster is over
    ``RASTER_CELL_LIMIT`` cells: not built, see docs/lab/reliability.md), or ``FAIL`` (anything else).
    """
    import parcover_env as pe

    source = str(path)
    try:
        scenario = pe.load_scenario(path)
    except ConfigError as exc:
        return _judge(exc, source)
    except Exception as exc:  # noqa: BLE001 - the point of the oracle
        return "FAIL", f"load_scenario: {type(exc).__name__}: {exc}"
    if raster_cells(scenario) > RASTER_CELL_LIMIT:
        return "huge", f"{scenario.map.size} at {scenario.planner.resolution} m"
    try:
        env = pe.parallel_env(path)
        obs, _ = env.reset(seed=0)
        for _ in range(steps):
            if not env.agents:
                break
            obs, *_ = env.step({a: np.array([1.0, 0.3]) for a in env.agents})
        bad = [a for a, o in obs.items() if not np.all(np.isfinite(o))]
        if bad:
            return "FAIL", f"non-finite observation for {bad}"
    except ConfigError as exc:
        return _judge(exc, source)
    except Exception as exc:  # noqa: BLE001
        return "FAIL", f"env: {type(exc).__name__}: {exc}"
    return "loaded", ""


def _judge(exc: ConfigError, source: str) -> tuple[str, str]:
    if exc.source != source:
        return "FAIL", f"ConfigError without the file name (source={exc.source!r}): {exc}"
    if not exc.key:
        return "FAIL", f"ConfigError without a key: {exc}"
    return "config_error", f"{exc.key}: {exc.message}"


def is_finite_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
