"""PPCP planning: roadmap over free space, parallel path coverage plan, exact solver, Kinect tree."""

from parcover_env.planning.exact import exact_min_robots, exact_minmax, held_karp
from parcover_env.planning.free_space import free_space_distances
from parcover_env.planning.kinect_tree import KinectTree, kinect_footprints, kinect_tree, plan_summary
from parcover_env.planning.plan import Branch, Plan, PlanTree, RobotPlan, TurningPoint
from parcover_env.planning.ppcp import metric_closure, solve_ppcp
from parcover_env.planning.roadmap import Roadmap, UnreachableKpoiError, build_roadmap, planner_clearance
from parcover_env.planning.scenario_plan import free_space_bound, plan_scenario, scenario_roadmap

__all__ = [
    "Branch", "KinectTree", "Plan", "PlanTree", "RobotPlan", "Roadmap", "TurningPoint",
    "UnreachableKpoiError",
    "build_roadmap", "exact_min_robots", "free_space_bound", "free_space_distances",
    "exact_minmax", "held_karp", "kinect_footprints", "kinect_tree",
    "metric_closure", "plan_scenario", "plan_summary", "planner_clearance", "scenario_roadmap", "solve_ppcp",
]
