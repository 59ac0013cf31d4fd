"""The checkpoint reader's pieces, on hand-made files: what each refusal says, and what it lets through."""

from __future__ import annotations

import pickle

import pytest

from parcover_env.errors import CheckpointError
from parcover_env.policies.checkpoint_files import as_int, as_widths, build_or_explain, first_line, load_torch_dict

torch = pytest.importorskip("torch")

KEYS = ("n_in", "hidden", "state_dict")


def test_first_line_keeps_the_type_and_the_first_sentence_of_a_long_message():
    assert first_line(ValueError("short\nsecond line")) == "ValueError: short"
    assert first_line(KeyError()) == "KeyError"
    long = "x" * 120 + ". And then advice that goes on"
    assert first_line(RuntimeError(long)) == "RuntimeError: " + "x" * 120
    assert len(first_line(RuntimeError("y" * 400))) == 160 and first_line(RuntimeError("y" * 400)).endswith("...")
    weights = RuntimeError("Weights only load failed. Advice.\nWeightsUnpickler error: Unsupported global: GLOBAL "
                           "x.Y was not allowed. Please use add_safe_globals")
    assert first_line(weights) == "RuntimeError: Unsupported global: GLOBAL x.Y was not allowed"
    assert first_line(RuntimeError("z" * 90 + ". tail")) == "RuntimeError: " + "z" * 90 + ". tail"  # short: kept


def test_integer_fields():
    assert as_int(4, "f", "BC actor", "n_in") == 4 and as_int(3.0, "f", "w", "k") == 3
    for bad, shown in (("x", "n_in must be an integer, got 'x'"), (None, "n_in must be an integer, got None"),
                       (2.5, "n_in must be an integer >= 1, got 2.5"), (0, "n_in must be an integer >= 1, got 0"),
                       (-3, "n_in must be an integer >= 1, got -3")):
        with pytest.raises(CheckpointError) as info:
            as_int(bad, "f.pt", "BC actor", "n_in")
        assert str(info.value) == f"cannot load BC actor f.pt: {shown}"
    assert as_widths([8, 4], "f", "w") == (8, 4) and as_widths((1,), "f", "w") == (1,) and as_widths([], "f", "w") == ()
    for bad in ("abc", 5, None, b"ab", [8, "x"], [0]):
        with pytest.raises(CheckpointError, match="hidden must be"):
            as_widths(bad, "f", "w")


def _save(tmp_path, obj, name="c.pt"):
    path = tmp_path / name
    torch.save(obj, path)
    return path


def test_a_dict_with_the_keys_is_returned_as_saved(tmp_path):
    saved = {"n_in": 3, "hidden": [4], "state_dict": {"w": torch.ones(2)}, "extra": 1}
    got = load_torch_dict(_save(tmp_path, saved), "BC actor", KEYS, weights_only=True)
    assert got.keys() == saved.keys() and torch.equal(got["state_dict"]["w"], torch.ones(2))


@pytest.mark.parametrize(("content", "weights_only", "problem"), [
    (b"", True, "the file is empty (0 bytes)"),
    (b"not a checkpoint", False, "not a torch checkpoint (corrupt, truncated or another format; "),
    (pickle.dumps({"n_in": 3}), False, "not a torch checkpoint (corrupt, truncated or another format; RuntimeError: "
                                       "Invalid magic number; corrupt file?)"),
])
def test_unreadable_files(tmp_path, content, weights_only, problem):
    path = tmp_path / "c.pt"
    path.write_bytes(content)
    with pytest.raises(CheckpointError) as info:
        load_torch_dict(path, "BC actor", KEYS, weights_only=weights_only)
    assert str(info.value).startswith(f"cannot load BC actor {path}: {problem}")
    assert info.value.path == str(path) and info.value.what == "BC actor"


def test_missing_files_and_directories(tmp_path):
    with pytest.raises(CheckpointError, match=r"nothing.pt: cannot read it \(No such file or directory\)$"):
        load_torch_dict(tmp_path / "nothing.pt", "BC actor", KEYS, weights_only=True)
    with pytest.raises(CheckpointError, match="not a torch checkpoint"):
        load_torch_dict(tmp_path, "BC actor", KEYS, weights_only=True)


def test_objects_other_than_tensors_are_refused_unpickled(tmp_path):
    path = _save(tmp_path, {"n_in": 3, "hidden": [4], "state_dict": {}, "obj": pickle.PickleError("x")})
    with pytest.raises(CheckpointError) as info:
        load_torch_dict(path, "TorchRL policy", KEYS, weights_only=True)
    assert str(info.value).startswith(f"cannot load TorchRL policy {path}: it holds Python objects other than tensors "
                                      "(UnpicklingError: Unsupported global: GLOBAL pickle.PickleError was not an "
                                      "allowed global")
    assert load_torch_dict(path, "BC actor", KEYS, weights_only=False)["n_in"] == 3  # trusted formats may hold them


def test_wrong_contents_name_what_is_missing_and_what_reads_it(tmp_path):
    with pytest.raises(CheckpointError, match=r": it holds a list, expected a dict with n_in, hidden, state_dict$"):
        load_torch_dict(_save(tmp_path, [1]), "BC actor", KEYS, weights_only=True)
    with pytest.raises(CheckpointError, match=r": not a BC actor checkpoint: no n_in \(it has hidden, state_dict\)$"):
        load_torch_dict(_save(tmp_path, {"hidden": [4], "state_dict": {}}), "BC actor", KEYS, weights_only=True)
    torchrl = {"obs_dim": 3, "act_dim": 2, "hidden": [4], "state_dict": {}}
    with pytest.raises(CheckpointError, match=r"\(it has act_dim, hidden, obs_dim, state_dict\); it looks like "
                                              r"torchrl:PATH \(a parcover train policy.pt\)$"):
        load_torch_dict(_save(tmp_path, torchrl), "BC actor", ("n_in", "n_out", *KEYS[1:]), weights_only=True)
    many = {f"k{i}": i for i in range(10)}
    with pytest.raises(CheckpointError, match=r"\(it has k0, k1, k2, k3, k4, k5, k6, k7, \.\.\.\)$"):
        load_torch_dict(_save(tmp_path, many), "BC actor", KEYS, weights_only=True)
    with pytest.raises(CheckpointError, match=r"\(it has nothing\)$"):
        load_torch_dict(_save(tmp_path, {}), "BC actor", KEYS, weights_only=True)
    critic = {"spec": {}, "state_dict": {}}
    with pytest.raises(CheckpointError, match=r"it looks like a parcover train critic.pt \(not a policy\)$"):
        load_torch_dict(_save(tmp_path, critic), "TorchRL policy", ("obs_dim", "act_dim", "hidden", "state_dict"),
                        weights_only=True)


def test_build_or_explain():
    assert build_or_explain("f.pt", "BC actor", lambda: 7) == 7

    def misfit():
        raise RuntimeError("size mismatch for 0.weight\nmore")

    with pytest.raises(CheckpointError) as info:
        build_or_explain("f.pt", "BC actor", misfit)
    assert str(info.value) == ("cannot load BC actor f.pt: its fields or weights do not fit the network it describes "
                               "(RuntimeError: size mismatch for 0.weight)")

    def bug():
        raise ZeroDivisionError

    with pytest.raises(ZeroDivisionError):  # not a checkpoint's fault: not dressed up as one
        build_or_explain("f.pt", "BC actor", bug)


def test_message_bounds():
    exact = RuntimeError("a" * 146)  # "RuntimeError: " + 146 = 160 characters: kept whole
    assert first_line(exact) == "RuntimeError: " + "a" * 146
    assert first_line(RuntimeError("a" * 147)) == "RuntimeError: " + "a" * 143 + "..."
    at_100 = "b" * 97 + ". c"  # a message of 100 characters is not cut at its first sentence
    assert first_line(RuntimeError(at_100)) == f"RuntimeError: {at_100}"
    many = RuntimeError("x " * 30 + "Advice. More. WeightsUnpickler error: Bad thing. Try this. Or that.")
    assert first_line(many) == "RuntimeError: Bad thing"
    sentences = RuntimeError("s" * 110 + ". Second. Third.")
    assert first_line(sentences) == "RuntimeError: " + "s" * 110
    long = "v" * 300
    with pytest.raises(CheckpointError) as info:
        as_int(long, "f.pt", "BC actor", "n_in")
    assert len(info.value.problem) == 200 and info.value.problem.startswith("n_in must be an integer, got 'vvv")
    with pytest.raises(CheckpointError) as info:
        as_widths(long, "f.pt", "BC actor")
    assert len(info.value.problem) == 200 and info.value.path == "f.pt" and info.value.what == "BC actor"
    with pytest.raises(CheckpointError) as info:
        as_int(-10**250, "f.pt", "BC actor", "n_in")
    assert len(info.value.problem) == 200


def test_every_refusal_names_the_file_and_the_kind(tmp_path):
    cases = [([1], "it holds a list"), ({"k": 1}, "no n_in, hidden, state_dict (it has k)"),
             ({f"k{i}": i for i in range(8)}, "(it has k0, k1, k2, k3, k4, k5, k6, k7)")]
    for saved, words in cases:
        path = _save(tmp_path, saved)
        with pytest.raises(CheckpointError) as info:
            load_torch_dict(path, "BC actor", KEYS, weights_only=True)
        assert (info.value.path, info.value.what) == (str(path), "BC actor") and words in str(info.value)
    with pytest.raises(CheckpointError) as info:
        load_torch_dict(tmp_path / "none.pt", "BC actor", KEYS, weights_only=True)
    assert (info.value.path, info.value.what) == (str(tmp_path / "none.pt"), "BC actor")
    path = _save(tmp_path, {"n_in": 3, "obj": pickle.PickleError("x")})
    with pytest.raises(CheckpointError) as info:
        load_torch_dict(path, "TorchRL policy", KEYS, weights_only=True)
    assert str(info.value).endswith("was not an allowed global by default): another program's or another policy's "
                                    "file, e.g. a bc: checkpoint (weights-only loading runs no code in it)")


def test_more_bounds():
    over_100 = "d" * 98 + ". e"  # 101 characters: cut at its first sentence
    assert first_line(RuntimeError(over_100)) == "RuntimeError: " + "d" * 98
    with pytest.raises(CheckpointError) as info:
        as_widths([8, "x"], "f.pt", "BC actor")
    assert (info.value.path, info.value.what, info.value.problem) == ("f.pt", "BC actor",
                                                                      "hidden must be an integer, got 'x'")


def test_nine_keys_are_shown_eight_and_an_ellipsis(tmp_path):
    path = _save(tmp_path, {f"k{i}": i for i in range(9)})
    with pytest.raises(CheckpointError, match=r"\(it has k0, k1, k2, k3, k4, k5, k6, k7, \.\.\.\)$"):
        load_torch_dict(path, "BC actor", KEYS, weights_only=True)
