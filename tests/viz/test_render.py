"""Frames (header band, legend, KPOI labels) and the streaming GIF writer."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np

import parcover_env
from parcover_env.viz.render import BAND, HEADER_PX, LEGEND_PX, GifRecorder, kpoi_label, render_frame, save_gif


def test_frame_has_header_and_legend_bands():
    env = parcover_env.parallel_env("office", render_mode="rgb_array")
    env.reset(seed=0)
    f = render_frame(env)
    assert f.dtype == np.uint8 and f.shape[2] == 3
    header, legend = f[:HEADER_PX], f[-LEGEND_PX:]
    assert (header == BAND).mean() > 0.8 and (header != BAND).any()  # dark band with text on it
    assert (legend == BAND).mean() > 0.6 and (legend != BAND).any()  # swatches and labels
    assert env.render().shape == f.shape


def test_kpoi_labels_are_one_based_everywhere():
    assert [kpoi_label(i) for i in range(3)] == ["K1", "K2", "K3"]
    import inspect

    from parcover_env.viz import plan

    assert "kpoi_label(i)" in inspect.getsource(plan.draw_plan)


def _frames(n):
    """n distinct frames (a gradient with a frame-dependent marker)."""
    base = np.tile(np.arange(0, 240, 15, dtype=np.uint8)[None, :, None], (16, 1, 3))
    out = []
    for k in range(n):
        f = base.copy()
        f[0, 0] = 10 * k
        out.append(f)
    return out


def test_gif_keeps_every_kth_and_the_final_frame(tmp_path):
    path = tmp_path / "a.gif"
    assert save_gif(path, _frames(7), fps=5, every=3) == 3  # frames 0, 3, 6 (6 is the last one)
    assert len(iio.imread(path, index=None)) == 3
    path2 = tmp_path / "b.gif"
    assert save_gif(path2, _frames(8), every=3) == 4  # 0, 3, 6 and the final frame 7
    got2 = iio.imread(path2, index=None)
    assert len(got2) == 4 and abs(int(got2[-1][0, 0, 0]) - 70) <= 8  # the final frame (marker 70), quantized


def test_gif_recorder_streams(tmp_path):
    rec = GifRecorder(tmp_path / "c.gif", every=1)
    rng = np.random.default_rng(0)
    for _ in range(3):
        rec.append(rng.integers(0, 255, (256, 256, 3), dtype=np.uint8))
    assert rec.written == 3 and (tmp_path / "c.gif").stat().st_size > 50_000  # on disk while still open
    rec.close()
    rec.close()  # idempotent
    assert len(iio.imread(tmp_path / "c.gif", index=None)) == 3
