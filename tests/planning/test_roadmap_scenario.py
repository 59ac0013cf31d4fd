"""Roadmap over a map and plan_scenario on shipped / hand-built scenarios."""

from __future__ import annotations

import json

import networkx as nx
import numpy as np
import pytest
import shapely
from shapely.geometry import LineString

from parcover_env.config import MapConfig, Pose, Scenario
from parcover_env.errors import ConfigError
from parcover_env.planning import (
    UnreachableKpoiError,
    build_roadmap,
    kinect_footprints,
    kinect_tree,
    plan_scenario,
    planner_clearance,
)
from parcover_env.planning.roadmap import edge_polyline
from parcover_env.scenarios import load_scenario
from parcover_env.world.map_model import MapModel

ROOMS = MapConfig(size=(6.0, 4.0), walls=(((3.0, 0.0), (3.0, 1.5)), ((3.0, 2.5), (3.0, 4.0))),
                  obstacles=(((1.0, 1.0), (2.0, 1.0), (2.0, 3.0), (1.0, 3.0)),))
KPOIS = ((0.3, 0.3), (5.7, 3.7), (5.7, 0.3), (1.5, 3.6))


@pytest.mark.parametrize("kind", ["medial_axis", "grid"])
def test_roadmap_connected_and_clear(kind):
    model = MapModel.from_config(ROOMS)
    radius, res = 0.15, 0.05
    rm = build_roadmap(model, (0.5, 2.0), KPOIS, planner_clearance(radius, res), res, kind, 0.25)
    g = rm.graph
    assert nx.is_connected(g) and {rm.start, *rm.kpois} <= set(g.nodes)
    for i, k in enumerate(rm.kpois):
        assert np.hypot(*(rm.node_pos(k) - KPOIS[i])) <= 0.25
    region = model.free.buffer(-radius)
    lines = [LineString(edge_polyline(g, u, v)) for u, v in g.edges]
    assert all(region.covers(ln) for ln in lines)
    for u, v, w in g.edges(data="weight"):
        poly = edge_polyline(g, u, v)
        np.testing.assert_allclose(poly[0], rm.node_pos(u))
        assert w == pytest.approx(np.linalg.norm(np.diff(poly, axis=0), axis=1).sum())


def test_roadmap_reports_unreachable_kpoi_index():
    closed = MapConfig(size=(4.0, 4.0), walls=(((2.0, 0.0), (2.0, 4.0)),))
    model = MapModel.from_config(closed)
    with pytest.raises(UnreachableKpoiError) as err:
        build_roadmap(model, (1.0, 2.0), [(0.5, 0.5), (3.0, 2.0)], 0.2, 0.05)
    assert err.value.index == 1
    with pytest.raises(ValueError, match="kind"):
        build_roadmap(model, (1.0, 2.0), [(0.5, 0.5)], 0.2, 0.05, kind="voronoi")


def _scenario(**kw) -> Scenario:
    base = dict(name="rooms", map=ROOMS, start=Pose(0.5, 2.0), kpois=KPOIS)
    base.update(kw)
    return Scenario(**base)


def test_plan_scenario_paths_keep_radius_and_cache():
    s = _scenario()
    plan = plan_scenario(s)
    assert plan is plan_scenario(s)
    region = MapModel.from_config(s.map, include_unknown=False).free.buffer(-(s.robot.radius - 1e-6))
    for rp in plan.robots:
        np.testing.assert_allclose(rp.path[0], (0.5, 2.0))
        assert region.covers(LineString(rp.path))
    assert sorted(k for rp in plan.robots for k in rp.kpois) == [0, 1, 2, 3]
    json.dumps(plan.to_dict())
    three = plan_scenario(s, n_robots=3)
    assert three.r == 3 and three.c_p >= three.c_max - 1e-9


def test_plan_scenario_ignores_unknown_obstacles():
    blocker = ((2.8, 1.55), (3.2, 1.55), (3.2, 1.95), (2.8, 1.95))  # half of the door, unknown to the map
    known = plan_scenario(_scenario(kpois=((5.5, 2.0),)))
    unknown_map = MapConfig(**{**ROOMS.__dict__, "unknown_obstacles": (blocker,)})
    with_unknown = plan_scenario(_scenario(kpois=((5.5, 2.0),), map=unknown_map))
    assert with_unknown.c_max == pytest.approx(known.c_max)
    # the known-map path goes through the door centre, where the unknown blocker sits
    assert LineString(with_unknown.robots[0].path).intersects(shapely.Polygon(blocker).buffer(0.15))


def test_narrow_door_kpoi_raises_config_error_naming_it():
    door = MapConfig(size=(4.0, 2.0), walls=(((2.0, 0.0), (2.0, 0.78)), ((2.0, 1.22), (2.0, 2.0))))
    s = _scenario(map=door, start=Pose(0.5, 1.0), kpois=((0.5, 0.5), (3.5, 1.0)))
    with pytest.raises(ConfigError, match=r"kpois\[1\]"):
        plan_scenario(s)
    with pytest.raises(ValueError, match="n_robots"):
        plan_scenario(s, n_robots=0)


def test_tree_scenario_is_fig6():
    """Seed A Fig. 6: 15 KPOI leaves, 4 TPs (one per hub), four Kinects linked A-B, A-C, A-D, B-D;
    the planner's optimum team is one robot per leaf."""
    s = load_scenario("tree")
    assert s.n_robots == "auto"
    plan = plan_scenario(s)
    assert plan.n_leaves == 15 and plan.r == 15 and plan.method == "paths"
    assert plan.c_p == pytest.approx(plan.c_max)
    assert len(plan.turning_points) == 4
    counts = sorted(sorted(b.n_robots for b in tp.branches) for tp in plan.turning_points)
    assert counts == [[1, 1, 1, 1, 1]] * 3 + [[5, 5, 5]]
    root_tp = min(plan.turning_points, key=lambda tp: tp.distance)
    assert root_tp.robots == (0, 15)
    kt = kinect_tree(kinect_footprints(s), plan, (s.start.x, s.start.y))
    assert kt.root == "A" and kt.unreached == ()
    assert kt.edges() == [["A", "B"], ["A", "C"], ["A", "D"], ["B", "D"]]
    # each TP is seen by a Kinect (Alg. 1 splits on a detection): A, C, D, B
    assert all(len(c) >= 1 for c in kt.tp_cover)
    assert len(kt.kpoi_cover) == len(s.kpois)
    json.dumps(kt.to_dict())


def test_kinect_tree_on_a_corridor_of_three_cameras():
    from planning_graphs import graph_from

    from parcover_env.planning import solve_ppcp

    g = graph_from({"s": (0.5, 0.5), "a": (5.5, 0.5), "b": (0.5, 3.5)}, [("s", "a"), ("s", "b")])
    plan = solve_ppcp(g, "s", ["a", "b"])
    fp = {"X": shapely.box(0, 0, 2, 1), "Y": shapely.box(1.8, 0, 4, 1), "Z": shapely.box(3.9, 0, 6, 1),
          "W": shapely.box(0, 2, 1, 4), "Q": shapely.box(10, 10, 11, 11)}
    kt = kinect_tree(fp, plan, (0.5, 0.5))
    assert kt.root == "X" and kt.parent == {"X": None, "Y": "X", "Z": "Y", "W": "X"}
    assert kt.links == {("X", "Y"): 1, ("Y", "Z"): 1, ("X", "W"): 1} and kt.unreached == ("Q",)
    assert kt.inputs("Y") == 1 and kt.outputs("X") == 2
    with pytest.raises(ValueError, match="footprint"):
        kinect_tree({}, plan, (0.5, 0.5))


def test_draw_plan_renders_tps_and_panel(tmp_path):
    from parcover_env.viz.plan import draw_plan, save_png

    s = _scenario()
    plan = plan_scenario(s)
    img = draw_plan(s, plan, scale_px_per_m=40)
    assert img.dtype == np.uint8 and img.shape[2] == 3 and img.shape[1] >= 6 * 40
    yellow = np.all(img == (240, 200, 0), axis=-1)
    assert yellow.sum() > 10 * len(plan.turning_points) > 0
    fp = {"A": shapely.box(0, 0, 3, 4), "B": shapely.box(3, 0, 6, 4)}
    with_panel = draw_plan(s, plan, kinect_tree(fp, plan, (0.5, 2.0)), scale_px_per_m=40)
    assert with_panel.shape[1] == img.shape[1] + 240
    save_png(tmp_path / "p.png", with_panel)
    assert (tmp_path / "p.png").stat().st_size > 1000
    with pytest.raises(ValueError, match="scale"):
        draw_plan(s, plan, scale_px_per_m=0)
