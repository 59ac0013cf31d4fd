"""Fuzzing the env API as a state machine: any order of ``reset`` (seeds and options of every
type), ``step`` (actions of every shape, dtype and container, NaN, inf, missing and unknown agents),
``render``, ``state``, the pose accessors and ``close``, before the first reset, mid-episode and after
the end. The fuzzed env has a twin that receives only the calls the fuzzed one accepted: every
accepted call returns the same, bit for bit, on both, and every rejected call is one ParcoverError
(or a standard error naming the argument) that leaves the env where it was."""

from __future__ import annotations

import copy
import dataclasses
import pickle

import numpy as np
from fuzz_files import fuzz_settings
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule

import parcover_env as pe
from parcover_env.errors import ActionError, ArgumentError, CallOrderError, ParcoverError

CONFIGS = {
    "office": dict(scenario="office", render_mode="rgb_array", max_cycles=12),
    "office_scan_ideal_v2": dict(scenario="office", preset="ideal", max_cycles=12,
                                 overrides={"observation": {"scan": {"enabled": True}, "version": 2}}),
}
_PRISTINE: dict = {}


def _fresh(name: str):
    """A never-reset env of config ``name`` (built once, then deep-copied: construction is the cost)."""
    if name not in _PRISTINE:
        _PRISTINE[name] = pe.parallel_env(**CONFIGS[name])
    return copy.deepcopy(_PRISTINE[name])


SEEDS = (st.none() | st.integers(-3, 2**70) | st.floats(allow_nan=True) | st.text(max_size=3) | st.booleans()
         | st.lists(st.integers(0, 3), max_size=2) | st.integers(0, 2**63 - 1).map(np.uint64)
         | st.integers(-3, 3).map(np.int64) | st.just(np.float64(2.0)))
OPTIONS = (st.none() | st.dictionaries(st.text(max_size=3), st.integers(), max_size=2) | st.integers()
           | st.text(max_size=2))

VALUES = st.floats(allow_nan=True, allow_infinity=True, width=32) | st.floats(-1, 1)
DTYPES = st.sampled_from(["float32", "float64", "float16", "int8", "int64", "uint8", "bool", "complex64", "object",
                          "U3"])


@st.composite
def one_action(draw, width: int):
    """One agent's action: mostly an array of the right shape, else another shape, dtype or container."""
    kind = draw(st.sampled_from(["good", "good", "good", "values", "shape", "dtype", "list", "scalar", "none", "str"]))
    if kind == "good":
        return np.array(draw(st.lists(st.floats(-1, 1, width=32), min_size=width, max_size=width)), np.float32)
    if kind == "values":
        return np.array(draw(st.lists(VALUES, min_size=width, max_size=width)), np.float64)
    if kind == "shape":
        shape = draw(st.sampled_from([(), (0,), (width - 1,), (width + 1,), (1, width), (width, 1)]))
        return np.zeros(shape, np.float32)
    if kind == "dtype":
        dtype = draw(DTYPES)
        try:
            return np.zeros(width, dtype=dtype)
        except TypeError:
            return np.array(["a"] * width)
    if kind == "list":
        return draw(st.lists(VALUES, min_size=width - 1, max_size=width + 1))
    if kind == "scalar":
        return draw(VALUES)
    return None if kind == "none" else draw(st.text(max_size=3))


@st.composite
def joint_action(draw, agents: list[str], width: int):
    """A joint action: a dict over the agents (some missing, some unknown, some not str), or not a dict."""
    shape = draw(st.sampled_from(["dict", "dict", "dict", "dict", "missing", "extra", "intkeys", "array", "list",
                                  "none", "empty"]))
    acts = {a: draw(one_action(width)) for a in agents}
    if shape == "missing" and acts:
        acts.pop(draw(st.sampled_from(sorted(acts))))
    elif shape == "extra":
        acts["robot_99"] = np.zeros(width, np.float32)
    elif shape == "intkeys":
        acts = {i: v for i, v in enumerate(acts.values())}
    elif shape == "array":
        return np.zeros((len(agents), width), np.float32)
    elif shape == "list":
        return list(acts.values())
    elif shape == "none":
        return None
    elif shape == "empty":
        return {}
    return acts


def _same(a, b, where: str) -> None:
    """``a`` and ``b`` (nested dicts, tuples, arrays, numbers) are equal, NaN equal to NaN."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        _same(vars(a), vars(b), where)
    elif isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for k in a:
            _same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray | float | np.floating):
        np.testing.assert_array_equal(a, b, err_msg=where)
    else:
        assert a == b, where


def _where(env) -> tuple:
    """Where an episode stands: agents, step count, the generator's state, the true and estimated poses."""
    if "world" not in vars(env):
        return (list(env.agents), None, None)
    return (list(env.agents), env.steps, repr(env.np_random.bit_generator.state), env.world.poses().tolist(),
            env.estimate.tolist())


def _rejected(exc: BaseException, words: tuple[str, ...]) -> None:
    """A rejected call: a ParcoverError, or a standard error naming one of ``words``, one short line."""
    text = str(exc)
    assert isinstance(exc, ParcoverError) or any(w in text for w in words), f"{type(exc).__name__}: {text}"
    assert "\n" not in text.strip() and len(text) < 400, text


class EnvMachine(RuleBasedStateMachine):
    """The fuzzed env and its twin (see the module docstring)."""

    @initialize(config=st.sampled_from(sorted(CONFIGS)))
    def build(self, config):
        self.env, self.twin = _fresh(config), _fresh(config)
        self.width = self.env.action_space("robot_0").shape[0]

    def _both(self, call, words: tuple[str, ...], *args, **kwargs):
        """``call`` on the fuzzed env; if accepted, on the twin too, with the same result."""
        before = _where(self.env)
        try:
            got = call(self.env, *args, **kwargs)
        except (ParcoverError, ValueError, TypeError, RuntimeError) as exc:
            _rejected(exc, words)
            assert _where(self.env) == before, "a rejected call changed the env"
            return exc
        want = call(self.twin, *args, **kwargs)
        _same(got, want, call.__name__)
        return None

    @rule(seed=SEEDS, options=OPTIONS)
    def reset(self, seed, options):
        if seed is None and self.env._rng is None:  # an unseeded first episode: the twin adopts its generator
            self.env.reset(seed=None, options=None)
            self.twin = copy.deepcopy(self.env)
            return
        exc = self._both(lambda e, **kw: e.reset(**kw), ("seed", "options"), seed=seed, options=options)
        if exc is not None:
            assert isinstance(exc, ArgumentError), exc
            assert ("seed" in str(exc)) or ("options" in str(exc))

    @rule(data=st.data())
    def step(self, data):
        acts = data.draw(joint_action(list(self.env.agents or self.env.possible_agents), self.width))
        exc = self._both(lambda e, a: e.step(a), ("action",), acts)
        if exc is not None and "world" not in vars(self.env):
            assert isinstance(exc, CallOrderError) and "call reset() first" in str(exc)
        elif exc is not None and not self.env.agents:
            assert isinstance(exc, CallOrderError) and "finished episode" in str(exc)
        elif exc is not None:
            assert isinstance(exc, ActionError), exc

    @rule(call=st.sampled_from(["render", "state", "true_poses", "pose_estimates", "pose_covariances", "route_done",
                                "kinect_frames", "localization_entries", "close"]))
    def accessor(self, call):
        exc = self._both(lambda e: getattr(e, call)(), (call,))
        if exc is not None:
            assert isinstance(exc, ParcoverError), exc
            if "world" not in vars(self.env):
                assert isinstance(exc, CallOrderError) and f"{call}() before the first reset()" in str(exc)

    @precondition(lambda self: "world" in vars(self.env))
    @rule()
    def copy_round_trip(self):
        """A pickled copy continues as the env does (a seeded step on each, compared)."""
        clone = pickle.loads(pickle.dumps(self.env))
        if self.env.agents:
            acts = {a: np.full(self.width, 0.5, np.float32) for a in self.env.agents}
            _same(clone.step(acts), copy.deepcopy(self.twin).step(acts), "pickled copy")

    @invariant()
    def twins_agree(self):
        if hasattr(self, "env"):
            assert _where(self.env) == _where(self.twin)


TestEnvMachine = EnvMachine.TestCase
TestEnvMachine.settings = settings(fuzz_settings(8), stateful_step_count=25)


@fuzz_settings(30)
@given(seed=SEEDS)
def test_single_robot_env_rejects_bad_seeds_before_seeding(seed):
    """The Gymnasium view checks the seed before Gymnasium's own seeding changes anything."""
    import gymnasium

    env = gymnasium.make("parcover_env/SingleRobotCoverage-v0").unwrapped
    env.reset(seed=4)
    obs, *_ = env.step(np.zeros(2, np.float32))
    state = repr(env.np_random.bit_generator.state), repr(env.par.np_random.bit_generator.state)
    try:
        env.reset(seed=seed)
    except ArgumentError as exc:
        assert "seed" in str(exc)
        assert (repr(env.np_random.bit_generator.state), repr(env.par.np_random.bit_generator.state)) == state


_VEC: list = []


@fuzz_settings(30)
@given(seed=SEEDS, options=OPTIONS | st.lists(OPTIONS, min_size=2, max_size=2))
def test_vec_env_checks_seeds_and_options_when_given(seed, options):
    """``VecEnv.seed`` and ``set_options`` check their values at once (not half-way through the next
    ``reset()``, after some worlds were reset) and keep the previous ones on a rejection."""
    if not _VEC:
        _VEC.append(pe.make_vec_env("office", n_envs=2, backend="batched"))
    vec = _VEC[0]
    if len(_VEC) == 1:
        vec.seed(5)
        _VEC.append(vec.reset())
    vec.seed(5)
    try:
        assert vec.seed(seed) == ([None, None] if seed is None else [int(seed), int(seed) + 1])
    except ArgumentError as exc:
        assert str(exc).startswith("seed(...): expected None or an integer >= 0, got ")
        np.testing.assert_array_equal(vec.reset(), _VEC[1])  # the previous seeds still hold
    try:
        vec.set_options(options)
    except ArgumentError as exc:
        assert "options" in str(exc)
