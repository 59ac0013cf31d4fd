"""The ``contact`` reward's :func:`touching` at its boundaries: a robot exactly ``radius + gap`` from
a wall, or exactly ``2 radius + gap`` from another robot, does not touch; a hair closer does."""

from __future__ import annotations

import numpy as np

from parcover_env.mission.rewards import touching

WALL = np.array([[0.0, -1.0, 0.0, 1.0]])  # the segment x = 0, -1 <= y <= 1


def test_a_robot_exactly_radius_plus_gap_from_a_wall_does_not_touch_it():
    xy = np.array([[0.5, 0.0], [-0.4375, 0.0], [0.5, 5.0]])  # r + gap = 0.5: on the edge, inside, far
    assert touching(xy, WALL, 0.25, 0.25).tolist() == [0.0, 1.0, 0.0]


def test_robots_exactly_two_radii_plus_gap_apart_do_not_touch():
    xy = np.array([[10.0, 0.0], [10.75, 0.0], [20.0, 0.0], [20.0, 0.6875]])  # 2 r + gap = 0.75
    assert touching(xy, WALL, 0.25, 0.25).tolist() == [0.0, 0.0, 1.0, 1.0]
    assert touching(xy, np.zeros((0, 4)), 0.25, 0.25).tolist() == [0.0, 0.0, 1.0, 1.0]


def test_integer_positions_are_touching_as_floats():
    xy = [[1, 0], [3, 0], [4, 0]]
    out = touching(xy, WALL, 0.5, 0.75)
    assert out.dtype == float and out.tolist() == [1.0, 1.0, 1.0]  # 1 m < 1.25 m from the wall; 1 m < 1.75 m apart
    assert touching(xy, WALL, 0.5, 0.25).tolist() == [0.0, 1.0, 1.0]  # 1 m >= 0.75 m from the wall; 1 m < 1.25 m


def test_the_term_table_names_real_weights_and_the_inputs_each_term_needs():
    import dataclasses

    from parcover_env.config import RewardConfig
    from parcover_env.mission.rewards import TEAM_TERMS, TERM_TABLE, TERMS, TERMS_V2, inputs_needed, paid_terms

    fields = {f.name for f in dataclasses.fields(RewardConfig)}
    assert {t.weight for t in TERM_TABLE.values()} <= fields
    assert TEAM_TERMS == ("kpoi", "time")
    assert inputs_needed(TERMS) == frozenset() and inputs_needed(paid_terms(TERMS_V2, RewardConfig())) == {"own_new"}
    assert inputs_needed(paid_terms(TERMS, RewardConfig(contact=1.0, uncertainty=1.0))) == {"touch", "sigma"}
    assert list(TERM_TABLE)[:5] == ["own_kpoi", *TERMS]  # a world sums its terms in the table's order


def test_a_term_pays_its_weight_times_its_input_by_name():
    from parcover_env.config import RewardConfig
    from parcover_env.mission.rewards import RewardInputs, reward_terms

    w = RewardConfig(kpoi=4.0, own_kpoi=3.0, progress=2.0, time=-0.5, collision=-1.5, contact=-0.25, uncertainty=-8.0)
    x = RewardInputs(np.array([2, 0]), np.array([[0.5, -1.0], [0.0, 0.25]]), np.array([[1, 0], [0, 3]]),
                     own_new=np.array([[1.0, 0.0], [0.0, 2.0]]), touch=np.array([[0.0, 1.0], [1.0, 0.0]]),
                     sigma=np.array([[0.125, 0.0], [0.5, 0.25]]))
    t = reward_terms(w, ("uncertainty", "kpoi", "own_kpoi", "progress", "time", "collision", "contact"), x)
    assert list(t) == ["uncertainty", "kpoi", "own_kpoi", "progress", "time", "collision", "contact"]
    assert t["kpoi"].tolist() == [[8.0, 8.0], [0.0, 0.0]] and t["own_kpoi"].tolist() == [[3.0, 0.0], [0.0, 6.0]]
    assert t["progress"].tolist() == [[1.0, -2.0], [0.0, 0.5]] and t["time"].tolist() == [[-0.5, -0.5]] * 2
    assert t["collision"].tolist() == [[-1.5, 0.0], [0.0, -4.5]]
    assert t["contact"].tolist() == [[0.0, -0.25], [-0.25, 0.0]]
    assert t["uncertainty"].tolist() == [[-1.0, 0.0], [-4.0, -2.0]]
