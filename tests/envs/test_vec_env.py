"""SB3 VecEnv adapter: slots per agent, seeding, truncation, agents that finish early."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.vec_env import VecMonitor  # noqa: E402

from parcover_env.envs.vec_env import ParallelVecEnv, _EnvFactory, make_vec_env  # noqa: E402
from parcover_env.mission.metrics import EpisodeMetrics  # noqa: E402


class FakeParallelEnv:
    """Agent i terminates after lengths[i] steps (and disappears); all truncate at max_steps."""

    metadata = {"render_modes": []}
    render_mode = None

    def __init__(self, lengths=(2, 3, 5), max_steps=100):
        self.lengths, self.max_steps = lengths, max_steps
        self.possible_agents = [f"a{i}" for i in range(len(lengths))]
        self.agents: list[str] = []
        self.reset_seeds: list = []
        self.received: list[dict] = []

    def observation_space(self, agent):
        return spaces.Box(-100, 100, (2,), np.float32)

    def action_space(self, agent):
        return spaces.Box(-1, 1, (1,), np.float32)

    def _obs(self):
        return {
            a: np.array([i + 1, self.t], np.float32)
            for i, a in enumerate(self.possible_agents)
            if a in self.agents
        }

    def reset(self, seed=None, options=None):
        self.reset_seeds.append(seed)
        self.t, self.agents = 0, list(self.possible_agents)
        return self._obs(), {a: {} for a in self.agents}

    def step(self, actions):
        self.received.append(dict(actions))
        assert set(actions) == set(self.agents)
        self.t += 1
        obs = self._obs()
        term = {a: self.t >= self.lengths[i] for i, a in enumerate(self.possible_agents) if a in self.agents}
        trunc = {a: self.t >= self.max_steps and not term[a] for a in term}
        rew = {a: 1.0 for a in term}
        infos = {a: EpisodeMetrics(1, 3, 1.0, 1.0).flat(ended=term[a] or trunc[a]) for a in term}
        self.agents = [a for a in self.agents if not (term[a] or trunc[a])]
        return obs, rew, term, trunc, infos

    def close(self):
        pass


def _venv(n=1, **kw):
    return ParallelVecEnv([lambda: FakeParallelEnv(**kw) for _ in range(n)])


def test_one_slot_per_agent_and_early_finishers():
    venv = _venv(n=2)
    assert venv.num_envs == 6
    obs = venv.reset()
    assert obs.shape == (6, 2) and obs[:, 1].tolist() == [0] * 6
    acts = np.zeros((6, 1), np.float32)
    venv.step(acts)
    obs, rew, done, infos = venv.step(acts)  # t = 2: a0 of both envs terminates
    assert done.tolist() == [True, False, False] * 2
    assert infos[0]["terminal_observation"].tolist() == [1, 2]
    assert infos[0]["TimeLimit.truncated"] is False
    assert infos[0]["metrics"]["n_robots"] == 3 and infos[0]["metrics"]["success"] is False
    assert "episode" not in infos[0]
    obs, rew, done, infos = venv.step(acts)  # t = 3: slot 0 idle, a1 terminates
    assert obs[0].tolist() == [0, 0] and rew[0] == 0 and not done[0] and infos[0]["active"] is False
    assert done[1] and rew[1] == 1
    inner = venv._envs[0].env
    assert set(inner.received[-1]) == {"a1", "a2"}  # the finished agent gets no action
    venv.step(acts)
    obs, rew, done, infos = venv.step(acts)  # t = 5: the last agent ends -> the env resets
    assert done.tolist() == [False, False, True] * 2
    assert infos[2]["terminal_observation"].tolist() == [3, 5]
    assert obs[:3].tolist() == [[1, 0], [2, 0], [3, 0]]


def test_truncation_flags():
    venv = _venv(lengths=(10, 10), max_steps=3)
    venv.reset()
    for _ in range(2):
        _, _, done, _ = venv.step(np.zeros((2, 1)))
        assert not done.any()
    _, _, done, infos = venv.step(np.zeros((2, 1)))
    assert done.all()
    assert all(i["TimeLimit.truncated"] for i in infos)
    assert infos[1]["terminal_observation"].tolist() == [2, 3]


def test_seed_gives_s_plus_i_then_none_on_autoreset():
    venv = _venv(n=3, lengths=(1,))
    assert venv.seed(10) == [10, 11, 12]
    venv.reset()
    venv.step(np.zeros((3, 1)))  # every episode ends -> automatic reset without a seed
    venv.reset()
    assert [e.env.reset_seeds for e in venv._envs] == [[10, None, None], [11, None, None], [12, None, None]]


def test_vecmonitor_counts_agent_episodes():
    venv = VecMonitor(_venv(lengths=(2, 4)))
    venv.reset()
    infos_all = []
    for _ in range(4):
        _, _, done, infos = venv.step(np.zeros((2, 1)))
        infos_all += [i for i, d in zip(infos, done, strict=False) if d]
    assert [i["episode"]["l"] for i in infos_all] == [2, 4]
    assert [i["episode"]["r"] for i in infos_all] == [2.0, 4.0]


def test_bad_inputs_raise_value_error():
    with pytest.raises(ValueError, match="env_fns"):
        ParallelVecEnv([])
    venv = _venv()
    venv.reset()
    with pytest.raises(ValueError, match="one per agent slot"):
        venv.step(np.zeros((2, 1)))

    class Mixed(FakeParallelEnv):
        def action_space(self, agent):
            return spaces.Box(-1, 1, (1 + (agent == "a1"),), np.float32)

    with pytest.raises(ValueError, match="identical spaces"):
        ParallelVecEnv([Mixed])


def test_real_env_multiprocess_matches_in_process():
    fns = [_EnvFactory("office", {"episode": {"max_steps": 30}}) for _ in range(2)]
    local, remote = ParallelVecEnv(fns), ParallelVecEnv(fns, multiprocess=True, start_method="fork")
    try:
        for v in (local, remote):
            v.seed(3)
        o1, o2 = local.reset(), remote.reset()
        np.testing.assert_array_equal(o1, o2)
        rng = np.random.default_rng(0)
        for _ in range(35):
            a = rng.uniform(-1, 1, (local.num_envs, 2)).astype(np.float32)
            r1, r2 = local.step(a), remote.step(a)
            for x, y in zip(r1[:3], r2[:3], strict=False):
                np.testing.assert_array_equal(x, y)
        assert remote.get_attr("n_robots") == [2, 2, 2, 2]
        assert r1[3][0]["active"] is True
    finally:
        local.close()
        remote.close()


def _train_params(seed: int) -> np.ndarray:
    import torch
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    venv = make_vec_env("office", n_envs=2, overrides={"episode": {"max_steps": 40}})
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=32,
        batch_size=32,
        n_epochs=2,
        seed=seed,
        device="cpu",
        policy_kwargs={"net_arch": [16]},
    )
    model.learn(total_timesteps=128)
    return torch.nn.utils.parameters_to_vector(model.policy.parameters()).detach().numpy()


def test_seeded_training_is_reproducible():
    a, b, c = _train_params(1), _train_params(1), _train_params(2)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_env_checker_on_single_agent_wrapper():
    from stable_baselines3.common.env_checker import check_env

    from parcover_env.envs.single_agent import SingleRobotCoverageEnv

    check_env(SingleRobotCoverageEnv("t_room"), warn=False)


def test_different_maps_share_one_vecenv():
    fns = [_EnvFactory("generated:3", None), _EnvFactory("generated:4", None)]
    venv = ParallelVecEnv(fns)
    sizes = [
        len(venv.get_attr("possible_agents", [0])[0]),
        len(venv.get_attr("possible_agents", [venv.num_envs - 1])[0]),
    ]
    assert venv.num_envs == sum(sizes)
    obs = venv.reset()
    assert venv.observation_space.contains(obs[0]) and venv.observation_space.contains(obs[-1])
    with pytest.raises(ValueError, match="shapes and action spaces must match"):
        ParallelVecEnv(
            [_EnvFactory("office", None), _EnvFactory("t_room", {"observation": {"sonar": False}})]
        )
