"""Learning curves: the series drawn against agent-steps and wall time, by value, on both panels."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.viz.curves import eval_series, learning_curve_figure, plot_learning_curves, smooth, training_series

pytest.importorskip("matplotlib")


def _write(path, header, rows):
    path.write_text(",".join(header) + "\n" + "".join(",".join(str(v) for v in r) + "\n" for r in rows))


def test_smooth_is_a_trailing_mean():
    np.testing.assert_allclose(smooth(np.array([0.0, 1.0, 0.5, 0.5]), 2), [0.0, 0.5, 0.75, 0.5])
    np.testing.assert_allclose(smooth(np.array([3.0, 1.0]), 5), [3.0, 2.0])
    with pytest.raises(ValueError, match="window"):
        smooth(np.array([1.0]), 0)


def test_series_by_value():
    rows = [{"agent_steps": 100.0, "wall_time": 60.0, "kpoi_fraction": 0.0},
            {"agent_steps": 200.0, "wall_time": 120.0, "kpoi_fraction": 1.0},
            {"agent_steps": 300.0, "wall_time": 240.0, "kpoi_fraction": 0.5}]
    s = training_series(rows, window=2)
    np.testing.assert_allclose(s.agent_steps, [100, 200, 300])
    np.testing.assert_allclose(s.wall_minutes, [1, 2, 4])
    np.testing.assert_allclose(s.value, [0.0, 0.5, 0.75])
    old = [{"timesteps": r["agent_steps"], **{k: v for k, v in r.items() if k != "agent_steps"}} for r in rows]
    np.testing.assert_allclose(training_series(old, window=2).agent_steps, [100, 200, 300])
    ev = [{"timesteps": 1000.0, "wall_time": 30.0, "kpoi_fraction": 0.2},
          {"timesteps": 1000.0, "wall_time": 42.0, "kpoi_fraction": 0.4},
          {"timesteps": 2000.0, "wall_time": 90.0, "kpoi_fraction": 1.0}]
    e = eval_series(ev)
    np.testing.assert_allclose(e.agent_steps, [1000, 2000])
    np.testing.assert_allclose(e.wall_minutes, [0.7, 1.5])
    np.testing.assert_allclose(e.value, [0.3, 1.0])


def test_figure_draws_each_run_against_agent_steps_and_wall_time(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    _write(run / "curve.csv", ["agent_steps", "wall_time", "episode_return", "kpoi_fraction", "success"],
           [[100, 60, -1, 0.0, 0], [200, 120, -1, 1.0, 1], [300, 240, -1, 0.5, 0]])
    _write(run / "eval.csv", ["timesteps", "wall_time", "kpoi_fraction"], [[150, 90, 0.25], [300, 300, 0.75]])
    fig = learning_curve_figure([run], window=2)
    steps_ax, wall_ax = fig.axes
    assert steps_ax.get_xlabel() == "agent-steps" and wall_ax.get_xlabel() == "wall time (min)"
    (train_s, eval_s), (train_w, eval_w) = steps_ax.lines, wall_ax.lines
    np.testing.assert_allclose(train_s.get_xydata(), [[100, 0.0], [200, 0.5], [300, 0.75]])
    np.testing.assert_allclose(train_w.get_xydata(), [[1, 0.0], [2, 0.5], [4, 0.75]])
    np.testing.assert_allclose(eval_s.get_xydata(), [[150, 0.25], [300, 0.75]])
    np.testing.assert_allclose(eval_w.get_xydata(), [[1.5, 0.25], [5, 0.75]])
    assert [t.get_text() for t in steps_ax.get_legend().get_texts()] == ["run", "run (eval)"]
    import matplotlib.pyplot as plt

    plt.close(fig)
    out = plot_learning_curves([run], tmp_path / "c.png", window=2)
    assert out.stat().st_size > 0


def test_a_fraction_is_drawn_on_its_whole_range_and_a_return_on_its_data(tmp_path):
    import matplotlib.pyplot as plt

    run = tmp_path / "run"
    run.mkdir()
    _write(run / "curve.csv", ["agent_steps", "wall_time", "episode_return", "kpoi_fraction", "success"],
           [[100, 60, -12.0, 0.2, 0], [200, 120, 30.0, 0.4, 0]])
    fig = learning_curve_figure([run], window=1)
    assert fig.axes[0].get_ylim() == pytest.approx((-0.05, 1.05))
    plt.close(fig)
    fig = learning_curve_figure([run], metric="episode_return", window=1)
    low, high = fig.axes[0].get_ylim()
    assert low <= -12.0 and high >= 30.0  # the returns are in view, not clipped to [0, 1]
    assert fig.axes[0].get_ylabel() == "episode return"
    plt.close(fig)
