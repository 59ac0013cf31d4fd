"""Minari round trip: recorded expert episodes saved, found by id pattern and read back unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.errors import ParcoverError

pytest.importorskip("minari")
pytest.importorskip("h5py")


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    from parcover_env.harness.datasets import record_episodes, save_minari

    out = tmp_path_factory.mktemp("datasets")
    eps = record_episodes("office", 1, seed=3, max_steps=25)
    save_minari(eps, "parcover/tiny-a-expert-v0", out, "office")
    save_minari(eps[:1], "parcover/tiny-b-expert-v0", out, "office")
    return out, eps


def test_saved_episodes_read_back_unchanged(root):
    from parcover_env.harness.datasets import load_minari

    out, eps = root
    back = load_minari("parcover/tiny-a-expert-v0", out)
    assert len(back) == len(eps) == 2  # office: one episode per robot
    for a, b in zip(eps, back, strict=True):
        np.testing.assert_array_equal(a["observations"], b["observations"])
        np.testing.assert_array_equal(a["actions"], b["actions"])
        np.testing.assert_allclose(a["rewards"], b["rewards"])
        assert len(b["actions"]) == 25 and bool(b["truncations"][-1])


def test_dataset_ids_expand_wildcards_and_lists(root):
    from parcover_env.harness.datasets import dataset_ids, load_minari_many

    out, eps = root
    assert dataset_ids("parcover/tiny-*-expert-v0", out) == ["parcover/tiny-a-expert-v0", "parcover/tiny-b-expert-v0"]
    assert dataset_ids("parcover/tiny-b-expert-v0, parcover/tiny-a-*", out) == [
        "parcover/tiny-b-expert-v0", "parcover/tiny-a-expert-v0"]
    many = load_minari_many("parcover/tiny-*", out)
    assert len(many) == 3  # 2 robot-episodes + 1
    np.testing.assert_array_equal(many[2]["actions"], eps[0]["actions"])
    with pytest.raises(ParcoverError, match="no Minari dataset"):
        dataset_ids("parcover/none-*", out)
    with pytest.raises(ParcoverError, match="parcover collect"):
        dataset_ids("parcover/missing-v0", out)
