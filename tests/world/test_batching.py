"""batching.stack: np.stack's values, cheaper."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.world.batching import stack


def test_stack_equals_np_stack_for_blocks_of_one_shape():
    rng = np.random.default_rng(0)
    for arrays in ([rng.random((15, 3)) for _ in range(4)], [rng.random(15) < 0.5 for _ in range(3)],
                   [np.arange(6).reshape(2, 3) + k for k in range(5)]):
        got, want = stack(arrays), np.stack(arrays)
        assert got.shape == want.shape and got.dtype == want.dtype and np.array_equal(got, want)
        assert not np.shares_memory(got, arrays[0])  # a block of its own
    assert stack([np.float64(1.5), np.float64(2.5)]).tolist() == [1.5, 2.5]  # 0-d: np.stack's way
    assert stack([[1, 2], [3, 4]]).tolist() == [[1, 2], [3, 4]]  # lists too


def test_stack_of_one_is_a_view_unless_copied():
    a = np.arange(3.0)
    view, copied = stack([a]), stack([a], copy=True)
    assert view.shape == (1, 3) and np.shares_memory(view, a)
    assert copied.tolist() == [[0.0, 1.0, 2.0]] and not np.shares_memory(copied, a)


def test_stack_of_mixed_shapes_fails_like_np_stack():
    with pytest.raises(ValueError):  # (2,), (1,) and (3,): 6 values, never a (3, 2) block
        stack([np.zeros(2), np.zeros(1), np.zeros(3)])
