"""The env's entry points refuse bad calls with one error naming the argument or the call to make
first, and a refused call changes nothing: the episode continues bit for bit as if it never came."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import parcover_env as pe
from parcover_env.envs.entry_checks import check_options, check_seed
from parcover_env.errors import ActionError, ArgumentError, CallOrderError, ParcoverError


def _steps(env, n: int, seed: int = 3) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        obs, *_ = env.step({a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents})
        out.append(np.stack([obs[a] for a in sorted(obs)]))
    return out


@pytest.mark.parametrize(("seed", "shown"), [("abc", "got str 'abc'"), (1.5, "got float 1.5"), (-1, "got -1"),
                                             (True, "got bool True"), ([1, 2], "got list [1, 2]")])
def test_a_bad_seed_is_one_argument_error_and_the_episode_goes_on(seed, shown):
    env, twin = pe.parallel_env("office"), pe.parallel_env("office")
    for e in (env, twin):
        e.reset(seed=7)
        _steps(e, 4)
    with pytest.raises(ArgumentError) as info:
        env.reset(seed=seed)
    assert str(info.value) == f"reset(seed=...): expected None or an integer >= 0, {shown}"
    assert isinstance(info.value, ValueError)  # also what numpy's and Gymnasium's users catch
    for a, b in zip(_steps(env, 5), _steps(twin, 5), strict=True):
        np.testing.assert_array_equal(a, b)
    assert pickle.loads(pickle.dumps(info.value)).args == info.value.args


def test_accepted_seeds():
    assert check_seed(None) is None
    assert check_seed(0) == 0 and check_seed(np.int64(5)) == 5 and check_seed(np.uint8(3)) == 3
    assert check_seed(2**70) == 2**70  # numpy's generators take any non-negative integer
    env = pe.parallel_env("office")
    a, _ = env.reset(seed=np.int64(4))
    b, _ = env.reset(seed=4)
    np.testing.assert_array_equal(a["robot_0"], b["robot_0"])


def test_options_must_be_a_mapping():
    check_options(None)
    check_options({})
    check_options({"anything": 1})  # PettingZoo's API test passes unknown options; none is read
    with pytest.raises(ArgumentError, match=r"^reset\(options=\.\.\.\): expected None or a dict, got list \[1\]$"):
        check_options([1])


@pytest.mark.parametrize("call", ["step", "state", "true_poses", "pose_estimates", "pose_covariances", "route_done",
                                  "kinect_frames", "render"])
def test_calls_before_the_first_reset_say_call_reset_first(call):
    env = pe.parallel_env("office", render_mode="rgb_array")
    with pytest.raises(CallOrderError) as info:
        env.step({}) if call == "step" else getattr(env, call)()
    assert str(info.value) == f"{call}() before the first reset(): call reset() first"
    assert isinstance(info.value, RuntimeError)
    env.close()
    env.close()  # closing twice is fine
    obs, _ = env.reset(seed=0)  # and the env is still usable
    assert set(obs) == set(env.possible_agents)


def test_step_after_the_end_and_route_done_of_v1():
    env = pe.parallel_env("office", max_cycles=2)
    env.reset(seed=0)
    _steps(env, 2)
    assert env.agents == []
    with pytest.raises(CallOrderError, match=r"^step\(\) called on a finished episode; call reset\(\) first$"):
        env.step({})
    with pytest.raises(ParcoverError, match=r"^route_done\(\) needs observation.version 2 \(parcover_v2\); this env "
                                            r"is version 1$"):
        env.route_done()


def test_the_single_robot_env_checks_the_seed_before_gymnasium_seeds():
    import gymnasium

    env = gymnasium.make("parcover_env/SingleRobotCoverage-v0").unwrapped
    env.reset(seed=2)
    before = repr(env.np_random.bit_generator.state)
    with pytest.raises(ArgumentError, match="seed"):
        env.reset(seed=-4)
    assert repr(env.np_random.bit_generator.state) == before
    a, _ = env.reset(seed=np.int64(9))  # a numpy integer: Gymnasium's own check refused it before
    b, _ = env.reset(seed=9)
    np.testing.assert_array_equal(a, b)


def test_the_aec_env_refuses_a_bad_action_when_it_is_given():
    """PettingZoo's converter buffered a NaN of the first robot and failed only at the last robot's
    turn, then at every later step (the NaN stayed in the buffer)."""
    env, twin = pe.env("office"), pe.env("office")
    for e in (env, twin):
        e.reset(seed=5)
    with pytest.raises(ActionError, match=r"^robot_0: action contains NaN or inf: \[nan, 0\.0\]$"):
        env.step(np.array([np.nan, 0.0], np.float32))
    assert env.agent_selection == "robot_0"
    rng = np.random.default_rng(0)
    for _ in range(6):  # the cycle goes on exactly as in the twin that never saw the NaN
        action = rng.uniform(-1, 1, 2).astype(np.float32)
        env.step(action)
        twin.step(action)
        assert env.agent_selection == twin.agent_selection
        np.testing.assert_array_equal(env.observe(env.agent_selection), twin.observe(twin.agent_selection))
        assert env.rewards == twin.rewards


def test_a_long_seed_is_shown_cut():
    with pytest.raises(ArgumentError) as info:
        check_seed("s" * 100)
    assert str(info.value) == "reset(seed=...): expected None or an integer >= 0, got str '" + "s" * 56 + "..."
    with pytest.raises(ArgumentError) as info:
        check_seed("t" * 58)  # its repr is 60 characters: shown whole
    assert str(info.value).endswith("got str '" + "t" * 58 + "'")
    with pytest.raises(ArgumentError) as info:
        check_seed("t" * 59, "seed(...)")
    assert str(info.value) == "seed(...): expected None or an integer >= 0, got str '" + "t" * 56 + "..."
