"""Rollouts do not depend on the CPU: numpy picks SIMD code for some functions (arctan2, exp, log,
...) by the CPU it runs on, and on CPUs with AVX-512 their last bits differ from the other CPUs'.
The simulation avoids those functions (``parcover_env.geometry.atan2``); here a process with numpy's
AVX-512 paths switched off must reproduce the rollouts of this one bit for bit."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from test_pinned_rollouts import rollout_hash  # noqa: E402

AVX512_TARGETS = ("X86_V4", "AVX512_ICL", "AVX512_SPR")


def _avx512_dispatch() -> list[str]:
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    return [t for t in AVX512_TARGETS if t in __cpu_dispatch__ and __cpu_features__.get(t)]


def test_numpy_arctan2_is_cpu_dependent_but_ours_is_not():
    """Documents why: on this CPU numpy's arctan2 may differ from libm's; ours never does."""
    import math

    from parcover_env.geometry import atan2

    g = np.random.default_rng(0)
    y, x = g.uniform(-5, 5, 4000), g.uniform(-5, 5, 4000)
    libm = np.array([math.atan2(a, b) for a, b in zip(y.tolist(), x.tolist(), strict=True)])
    assert np.array_equal(atan2(y, x), libm)
    assert atan2(y[:, None], x[None, :3]).shape == (4000, 3)
    assert atan2(1.0, -1.0) == math.atan2(1.0, -1.0) == pytest.approx(3 * math.pi / 4)
    assert atan2(y[:5], 0.5).tolist() == [math.atan2(v, 0.5) for v in y[:5].tolist()]  # one scalar, one array
    assert atan2(-2.0, x[:5]).tolist() == [math.atan2(-2.0, v) for v in x[:5].tolist()]
    assert atan2([1, 2], [2, 1]).tolist() == [math.atan2(1, 2), math.atan2(2, 1)]


def _hashes_in_a_process(env: dict[str, str]) -> list[str]:
    code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
            "from test_pinned_rollouts import rollout_hash; "
            "print(' '.join(rollout_hash(s, 5, expert=True, steps=80) for s in ('office', 'tree')))")
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, **env}, capture_output=True, text=True,
                         check=True)
    return out.stdout.split()


def test_rollouts_equal_with_numpy_avx512_paths_switched_off():
    targets = _avx512_dispatch()
    if not targets:
        pytest.skip("numpy takes no AVX-512 paths on this CPU")
    here = [rollout_hash(s, 5, expert=True, steps=80) for s in ("office", "tree")]
    assert _hashes_in_a_process({"NPY_DISABLE_CPU_FEATURES": " ".join(targets)}) == here


def test_rollouts_equal_with_another_blas_kernel():
    """OpenBLAS picks its kernels by CPU too; an older CPU's kernels must give the same rollouts."""
    here = [rollout_hash(s, 5, expert=True, steps=80) for s in ("office", "tree")]
    assert _hashes_in_a_process({"OPENBLAS_CORETYPE": "Sandybridge"}) == here
