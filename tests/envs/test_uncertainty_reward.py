"""The optional ``uncertainty`` reward term: per step and metre of the agent's ``sigma_major`` (its
estimate's own covariance after the step's fixes), pinned by value on hand-built covariances and in
the env against the observation's ``sigma_major`` entry; with weight 0 (the default) no such term."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from parcover_env import parcover_v2
from parcover_env.config import RewardConfig
from parcover_env.mission.rewards import TERMS, TERMS_V2, RewardInputs, paid_terms, reward_terms, sigma_major
from parcover_env.sim import act_phase, score_phase


def _cov(a: float, b: float, c: float, h: float = 0.01) -> np.ndarray:
    return np.array([[a, b, 0.0], [b, c, 0.0], [0.0, 0.0, h]])


def test_sigma_major_is_the_root_of_the_larger_xy_eigenvalue():
    cov = np.stack([_cov(0.04, 0.0, 0.01),  # axis-aligned: sqrt(0.04) = 0.2
                    _cov(0.01, 0.0, 0.09),  # the y axis is the major one: 0.3
                    _cov(0.05, 0.03, 0.05),  # eigenvalues 0.08 and 0.02
                    _cov(0.0, 0.0, 0.0, h=4.0)])  # heading variance is not position uncertainty
    np.testing.assert_allclose(sigma_major(cov), [0.2, 0.3, np.sqrt(0.08), 0.0], rtol=1e-12)
    block = np.stack([cov[:2], cov[2:]])  # K worlds x N robots
    np.testing.assert_allclose(sigma_major(block), [[0.2, 0.3], [np.sqrt(0.08), 0.0]], rtol=1e-12)


def test_reward_terms_pay_the_uncertainty_weight_per_metre_last():
    w = RewardConfig(contact=-0.1, uncertainty=-2.0)
    sigma = np.array([0.1, 0.0, 0.25])
    t = reward_terms(w, paid_terms(TERMS_V2, RewardConfig(contact=1.0, uncertainty=1.0)),
                     RewardInputs(0, np.zeros(3), np.zeros(3, int), np.zeros(3), touch=np.zeros(3), sigma=sigma))
    assert list(t) == [*TERMS_V2, "contact", "uncertainty"]
    np.testing.assert_allclose(t["uncertainty"], [-0.2, 0.0, -0.5], rtol=1e-12)
    alone = RewardConfig(uncertainty=1.0)
    paid = paid_terms(TERMS, alone)
    assert paid == (*TERMS, "uncertainty")
    assert list(reward_terms(w, paid, RewardInputs(0, np.zeros(3), np.zeros(3, int), sigma=sigma)))[-1] == "uncertainty"
    assert paid_terms(TERMS_V2, RewardConfig(uncertainty=1.0)) == (*TERMS_V2, "uncertainty")
    assert "uncertainty" not in paid_terms(TERMS_V2, RewardConfig(contact=1.0))


def _env(uncertainty: float):
    rewards = {"uncertainty": uncertainty} if uncertainty else {}
    return parcover_v2.parallel_env("office", overrides={"rewards": rewards})


def _drive(env):
    return {a: np.array([0.6, 0.1], np.float32) for a in env.agents}


def test_env_pays_the_weight_times_the_observed_sigma_major_every_step():
    env = _env(-1.5)
    obs, _ = env.reset(seed=3)
    assert env.terms[-1] == "uncertainty"
    lay = env.layout
    seen = []
    for _ in range(40):  # driving: the odometry covariance grows between fixes
        obs, rew, _, _, infos = env.step(_drive(env))
        for a in env.possible_agents:
            sig = float(lay.get(obs[a], "sigma_major")[0])
            assert infos[a]["reward_uncertainty"] == pytest.approx(-1.5 * sig, rel=1e-6)  # the entry is float32
            assert rew[a] == pytest.approx(sum(infos[a][f"reward_{t}"] for t in env.terms), abs=1e-12)
            seen.append(sig)
    assert max(seen) > 0.0  # a real cost was paid, not zeros


def test_env_after_a_fix_pays_the_fixed_covariance():
    env = _env(-1.0)
    env.reset(seed=0)
    follower = int(np.flatnonzero(~env.team.leader)[0])  # no Kinect fix overrides it this step
    env.estimator.fix(follower, env.estimate[follower].copy(), np.diag([0.09, 0.04, 0.01]))  # sigma_major 0.3 m
    acts = {a: np.zeros(2, np.float32) for a in env.agents}  # standing still: the covariance holds
    _, _, _, _, infos = env.step(acts)
    assert infos[f"robot_{follower}"]["reward_uncertainty"] == pytest.approx(-0.3, abs=1e-3)


def test_uncertainty_term_keeps_copies_bit_identical():
    env = _env(-1.0)
    env.reset(seed=5)
    for _ in range(10):
        env.step(_drive(env))
    twin = copy.deepcopy(env)
    for _ in range(15):
        _, r1, _, _, _ = env.step(_drive(env))
        _, r2, _, _, _ = twin.step(_drive(twin))
        assert r1 == r2


def test_env_without_uncertainty_weight_has_no_uncertainty_term():
    env = _env(0.0)
    env.reset(seed=0)
    _, _, _, _, infos = env.step(_drive(env))
    assert env.terms == TERMS_V2 and "reward_uncertainty" not in infos["robot_0"]


def test_score_phase_pays_each_worlds_own_sigma_in_any_order_of_the_worlds():
    envs = [_env(-2.0) for _ in range(2)]
    rng = np.random.default_rng(4)
    for seed, e in enumerate(envs):
        e.reset(seed=seed)
        for _ in range(6 + 9 * seed):  # different covariances
            e.step({a: rng.uniform(-1, 1, 2).astype(np.float32) for a in e.agents})
    acts = rng.uniform(-1, 1, (2, envs[0].n_robots, 2)).astype(np.float32)
    twins = copy.deepcopy(envs[::-1])  # the same worlds in the other order
    acted = act_phase.act(envs, acts)
    want = [-2.0 * sigma_major(e.estimator.covariance) for e in envs]
    assert not np.allclose(want[0], want[1])
    scores = score_phase.score(envs, acted)  # the act phase's shared rows
    assert scores.act is acted.rows
    np.testing.assert_allclose(scores.terms["uncertainty"], want, rtol=1e-12)
    scores = score_phase.score(twins, act_phase.act(twins, acts[::-1]))
    np.testing.assert_array_equal(scores.terms["uncertainty"], np.asarray(want)[::-1])  # bit for bit
