"""SelectEntries: the networks see exactly the kept observation entries."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")


def test_keep_indices_drop_named_fields_of_the_layout():
    from parcover_env import parallel_env
    from parcover_env.policies.sb3_features import keep_indices

    lay = parallel_env("office").layout
    keep = keep_indices(lay.names, lay.slices, ["x", "y", "cos_theta", "sin_theta"])
    assert keep == list(range(4, lay.size))  # the four world-frame entries lead the layout
    sonar = lay.slices["sonar"]
    keep2 = keep_indices(lay.names, lay.slices, ["sonar"])
    assert len(keep2) == lay.size - (sonar.stop - sonar.start) and sonar.start not in keep2
    with pytest.raises(ValueError, match="unknown observation fields"):
        keep_indices(lay.names, lay.slices, ["z"])


def test_select_entries_forwards_only_the_kept_columns():
    import gymnasium as gym

    from parcover_env.policies.sb3_features import SelectEntries

    space = gym.spaces.Box(-1.0, 1.0, shape=(5,), dtype=np.float32)
    ext = SelectEntries(space, keep=[4, 1, 2])
    x = torch.arange(10, dtype=torch.float32).reshape(2, 5)
    assert ext.features_dim == 3
    assert ext(x).tolist() == [[4.0, 1.0, 2.0], [9.0, 6.0, 7.0]]
    with pytest.raises(ValueError, match="distinct indices"):
        SelectEntries(space, keep=[0, 5])


def test_ppo_with_hidden_pose_ignores_it_and_survives_save_load(tmp_path):
    import gymnasium as gym
    from stable_baselines3 import PPO

    from parcover_env.policies.sb3_features import SelectEntries

    env = gym.make("Pendulum-v1")  # 3 entries: cos, sin, angular velocity
    model = PPO("MlpPolicy", env, seed=0, n_steps=64, batch_size=64,
                policy_kwargs={"features_extractor_class": SelectEntries, "features_extractor_kwargs": {"keep": [2]}})
    a = np.array([[0.3, -0.2, 0.5]], dtype=np.float32)
    b = np.array([[-0.9, 0.7, 0.5]], dtype=np.float32)  # differs only in hidden entries
    assert np.array_equal(model.predict(a, deterministic=True)[0], model.predict(b, deterministic=True)[0])
    c = np.array([[0.3, -0.2, -4.0]], dtype=np.float32)  # differs in the kept one
    assert not np.array_equal(model.predict(a, deterministic=True)[0], model.predict(c, deterministic=True)[0])
    model.save(tmp_path / "m.zip")
    back = PPO.load(tmp_path / "m.zip", device="cpu")
    assert back.policy.features_extractor.features_dim == 1
    np.testing.assert_allclose(back.predict(c, deterministic=True)[0], model.predict(c, deterministic=True)[0])
