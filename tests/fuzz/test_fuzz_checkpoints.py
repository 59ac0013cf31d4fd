"""Checkpoint files: every broken file (empty, corrupt, truncated anywhere, another format, another
policy's, fields that do not fit) behind every checkpoint spec is one CheckpointError naming the
file and what is wrong; from the CLI, one line and status 2 (``run`` and ``bench``, also across
bench's worker processes)."""

from __future__ import annotations

import pickle
import tempfile
from pathlib import Path

import numpy as np
import pytest
from cli_outcome import run_cli
from fuzz_files import BROKEN, OFFICE_OBS, bc_checkpoint, files, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st

import parcover_env as pe
from parcover_env.errors import CheckpointError, ParcoverError
from parcover_env.policies.registry import make_policy

torch = pytest.importorskip("torch")

KINDS = ("bc", "torchrl", "torchrl_sampled", "ppo")


@pytest.fixture(scope="module")
def office():
    env = pe.parallel_env("office")
    assert env.observation_space("robot_0").shape == (OFFICE_OBS,)
    return env


def _load(kind: str, path: Path, env) -> ParcoverError | None:
    """The error of building policy ``kind:path`` for ``env`` (None: it loaded)."""
    try:
        make_policy(f"{kind}:{path}", env, 0)
    except ParcoverError as exc:
        return exc
    return None


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", BROKEN)
def test_every_broken_file_is_one_checkpoint_error(kind, name, office):
    path = files()[name]
    exc = _load(kind, path, office)
    assert isinstance(exc, CheckpointError), f"{kind}:{name}: {exc!r}"
    assert str(path) in str(exc) and exc.path.startswith(str(path))
    assert "\n" not in str(exc) and len(str(exc)) < 400, str(exc)
    back = pickle.loads(pickle.dumps(exc))  # crosses bench's worker processes as itself
    assert type(back) is CheckpointError and str(back) == str(exc) and back.path == exc.path


@pytest.mark.parametrize(("kind", "name", "words"), [
    ("bc", "empty", "the file is empty (0 bytes)"),
    ("bc", "junk", "not a torch checkpoint (corrupt, truncated or another format; UnpicklingError"),
    ("bc", "bc_tail", "not a torch checkpoint (corrupt, truncated or another format; OSError: [Errno 22]"),
    ("bc", "bc_trunc", "not a torch checkpoint (corrupt, truncated or another format; RuntimeError"),
    ("bc", "list", "it holds a list, expected a dict with n_in, n_out, hidden"),
    ("bc", "torchrl", "not a BC actor checkpoint: no n_in, n_out, obs_mean, obs_std (it has act_dim, hidden, "
                      "obs_dim, state_dict); it looks like torchrl:PATH"),
    ("torchrl", "bc", "it holds Python objects other than tensors (UnpicklingError: Unsupported global"),
    ("torchrl", "nokeys", "not a TorchRL policy checkpoint: no obs_dim, act_dim, hidden, state_dict (it has foo)"),
    ("bc", "bc_shape", "its fields or weights do not fit the network it describes (RuntimeError: Error(s) in "
                       "loading state_dict"),
    ("bc", "bc_hidden", "hidden must be a list of layer widths, got 'abc'"),
    ("ppo", "bc", "not an SB3 PPO model.zip"),
])
def test_the_error_says_what_is_wrong(kind, name, words, office):
    exc = _load(kind, files()[name], office)
    what = {"bc": "BC actor", "torchrl": "TorchRL policy", "ppo": "PPO checkpoint"}[kind]
    assert str(exc).startswith(f"cannot load {what} {files()[name]}"), str(exc)
    assert words in str(exc), str(exc)


def test_a_valid_bc_file_loads_and_acts(office):
    """The loader's checks do not refuse a good file: the saved net acts as saved."""
    policy = make_policy(f"bc:{files()['bc']}", office, 0)
    obs, _ = office.reset(seed=0)
    net = torch.nn.Sequential(torch.nn.Linear(OFFICE_OBS, 8), torch.nn.ReLU(), torch.nn.Linear(8, 2),
                              torch.nn.Tanh())
    net.load_state_dict(bc_checkpoint(OFFICE_OBS)["state_dict"])
    with torch.no_grad():  # obs_mean 0, obs_std 1: the normalization is a clip to [-10, 10]
        want = net(torch.as_tensor(np.clip(obs["robot_0"], -10, 10)[None])).numpy()[0]
    np.testing.assert_allclose(policy.act(obs)["robot_0"], want, rtol=1e-6)


def test_the_removed_mappo_spec_is_one_argument_error_and_its_files_load_as_bc(tmp_path, office):
    """``mappo:`` (the removed hand-written trainer's actor.pt) names the replacement; the old file, the
    bc: format plus two fields, still acts through ``bc:DIR/actor.pt`` exactly as a bc.pt does."""
    from parcover_env.errors import ArgumentError

    torch.save(bc_checkpoint(OFFICE_OBS, algorithm="mappo", critic_state_dim=13), tmp_path / "actor.pt")
    with pytest.raises(ArgumentError) as info:
        make_policy(f"mappo:{tmp_path}", office, 0)
    assert str(info.value).startswith(f"policy 'mappo:{tmp_path}': mappo: checkpoints of the removed hand-written "
                                      "trainer (baselines/train_mappo.py) are no longer a spec; use torchrl:")
    assert str(info.value).endswith("an old DIR/actor.pt has the bc: format and loads as bc:DIR/actor.pt")
    back = pickle.loads(pickle.dumps(info.value))
    assert type(back) is ArgumentError and str(back) == str(info.value)
    status, out, err = run_cli(["run", "office", "--policy", f"mappo:{tmp_path}", "--steps", "2", "--quiet"])
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and lines[0].startswith("parcover: error: policy 'mappo:"), err
    obs, _ = office.reset(seed=0)
    old = make_policy(f"bc:{tmp_path / 'actor.pt'}", office, 0).act(obs)
    new = make_policy(f"bc:{files()['bc']}", office, 0).act(obs)
    assert set(old) == set(obs) and all(np.array_equal(old[a], new[a]) for a in obs)


_MUTATED = Path(tempfile.mkdtemp(prefix="parcover_ckpt_fuzz_"))


@st.composite
def mutated(draw) -> tuple[str, bytes]:
    """A valid checkpoint's bytes (BC or TorchRL), cut, flipped in a few places or wrapped in junk."""
    source = draw(st.sampled_from(["bc", "torchrl"]))
    data = bytearray(files()[source].read_bytes())
    how = draw(st.sampled_from(["cut", "flip", "prefix", "suffix"]))
    if how == "cut":
        data = data[: draw(st.integers(0, len(data) - 1))]
    elif how == "flip":
        for _ in range(draw(st.integers(1, 4))):
            data[draw(st.integers(0, len(data) - 1))] ^= draw(st.integers(1, 255))
    elif how == "prefix":
        data = bytearray(draw(st.binary(min_size=1, max_size=16))) + data
    else:
        data += draw(st.binary(min_size=1, max_size=16))
    return source, bytes(data)


@fuzz_settings(25)
@given(case=mutated(), kind=st.sampled_from(["bc", "torchrl", "torchrl_sampled"]))
def test_fuzz_mutated_checkpoints(case, kind):
    """A damaged checkpoint either still loads (a flipped byte in a weight) or is one CheckpointError."""
    _, data = case
    path = _MUTATED / "policy.pt"
    path.write_bytes(data)
    env = _office_once()
    try:
        make_policy(f"{kind}:{path}", env, 0)
    except CheckpointError as exc:
        assert str(path) in str(exc) and "\n" not in str(exc)
    except ParcoverError as exc:  # loaded, but trained on other observations
        assert "was trained on observations of shape" in str(exc)


_ENV: list = []


def _office_once():
    if not _ENV:
        _ENV.append(pe.parallel_env("office"))
    return _ENV[0]


@pytest.mark.parametrize("kind", ["bc", "torchrl"])
def test_cli_run_with_a_broken_checkpoint_is_one_line(kind):
    path = files()["junk"]
    status, out, err = run_cli(["run", "office", "--policy", f"{kind}:{path}", "--steps", "2", "--quiet"])
    assert status == 2 and out.count("\n") <= 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("parcover: error: cannot load ") and str(path) in lines[0]


def test_cli_bench_with_broken_checkpoints_is_one_line_across_workers(tmp_path):
    """Formerly three tracebacks: the workers' errors reach the parent as one CheckpointError."""
    spec = f"bc:{files()['empty']}"
    status, _, err = run_cli(["bench", "office", "--policies", f"random,{spec}", "--seeds", "2", "--max-steps", "2",
                              "--workers", "2", "--no-plots", "--quiet", "--out", str(tmp_path)])
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1, err
    assert lines[0] == f"parcover: error: cannot load BC actor {files()['empty']}: the file is empty (0 bytes)"
