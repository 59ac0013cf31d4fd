"""Compare two tiny agents of your own (SB3 PPO and TorchRL PPO) with the expert on office.

The code of docs/tutorials/compare_your_policy.md, as a script."""

from __future__ import annotations

import argparse

import numpy as np
import torch

import parcover_env
from parcover_env.policies import Policy

SCENARIO = "office"
SEEDS = [1000, 1001]  # the evaluation seeds of `parcover bench` (trainers use seeds < 1000)


def train_sb3(steps: int = 4096, seed: int = 0):
    """SB3 PPO on office for `steps` robot-steps (two robots: half as many env steps)."""
    from stable_baselines3 import PPO

    venv = parcover_env.make_vec_env(SCENARIO, n_envs=1)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, seed=seed, device="cpu", verbose=0)
    model.learn(total_timesteps=steps)
    venv.close()
    return model


class SB3Policy(Policy):
    """A trained SB3 model as a Policy: every robot acts on its own observation."""

    def __init__(self, model):
        self.model = model
        self.obs_shape = model.observation_space.shape

    def act(self, observations):
        agents = sorted(observations)
        obs = np.stack([observations[a] for a in agents])
        actions, _ = self.model.predict(obs, deterministic=True)
        return {a: np.clip(actions[i], -1.0, 1.0).astype(np.float32) for i, a in enumerate(agents)}


def train_torchrl(iterations: int = 10, frames: int = 256, epochs: int = 4, seed: int = 0):
    """A few PPO iterations of a plain TorchRL actor-critic on office; returns the actor."""
    from tensordict.nn import NormalParamExtractor, TensorDictModule
    from torch import nn
    from torchrl.modules import MLP, ProbabilisticActor, TanhNormal
    from torchrl.objectives import ClipPPOLoss, ValueEstimators

    from parcover_env.harness.marl_env import RobotsEnv

    torch.manual_seed(seed)
    env = RobotsEnv(parcover_env.parallel_env(SCENARIO))
    env.set_seed(seed)
    obs_dim = env.observation_spec["robot", "observation"].shape[-1]
    act_dim = env.action_spec["robot", "action"].shape[-1]
    body = nn.Sequential(MLP(in_features=obs_dim, out_features=2 * act_dim, num_cells=[64, 64]),
                         NormalParamExtractor())
    actor = ProbabilisticActor(
        TensorDictModule(body, in_keys=[("robot", "observation")], out_keys=[("robot", "loc"), ("robot", "scale")]),
        in_keys=[("robot", "loc"), ("robot", "scale")], out_keys=[("robot", "action")],
        distribution_class=TanhNormal, distribution_kwargs={"low": -1.0, "high": 1.0}, return_log_prob=True)
    critic = TensorDictModule(MLP(in_features=obs_dim, out_features=1, num_cells=[64, 64]),
                              in_keys=[("robot", "observation")], out_keys=[("robot", "state_value")])
    loss = ClipPPOLoss(actor, critic)
    loss.set_keys(reward=("robot", "reward"), action=("robot", "action"), value=("robot", "state_value"),
                  done=("robot", "done"), terminated=("robot", "terminated"),
                  sample_log_prob=("robot", "action_log_prob"))
    loss.make_value_estimator(ValueEstimators.GAE, gamma=0.99, lmbda=0.95)
    optim = torch.optim.Adam(loss.parameters(), lr=3e-4)
    for _ in range(iterations):
        with torch.no_grad():
            batch = env.rollout(frames, actor, break_when_any_done=False)
        for _ in range(epochs):
            terms = loss(batch)
            optim.zero_grad()
            (terms["loss_objective"] + terms["loss_critic"] + terms["loss_entropy"]).backward()
            optim.step()
    return actor


class TorchRLPolicy(Policy):
    """A TorchRL actor of the group "robot" as a Policy (its deterministic action)."""

    def __init__(self, actor, obs_dim: int):
        self.actor = actor
        self.obs_shape = (obs_dim,)

    def act(self, observations):
        from tensordict import TensorDict
        from torchrl.envs.utils import ExplorationType, set_exploration_type

        agents = sorted(observations)
        obs = torch.as_tensor(np.stack([observations[a] for a in agents]), dtype=torch.float32)
        td = TensorDict({"robot": TensorDict({"observation": obs}, batch_size=[len(agents)])}, batch_size=[])
        with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
            actions = self.actor(td)["robot", "action"].numpy()
        return {a: actions[i].astype(np.float32) for i, a in enumerate(agents)}


def main(sb3_steps: int = 4096, torchrl_iterations: int = 10, torchrl_frames: int = 256, seeds=SEEDS,
         max_steps: int | None = None):
    """Train both agents, compare them with the expert, print the table; returns the Comparison."""
    torch.set_num_threads(1)  # small networks: one thread acts fastest, and leaves the env a core
    sb3 = SB3Policy(train_sb3(sb3_steps))
    obs_dim = parcover_env.parallel_env(SCENARIO).observation_space("robot_0").shape[0]
    torchrl = TorchRLPolicy(train_torchrl(torchrl_iterations, torchrl_frames), obs_dim)
    result = parcover_env.compare({"sb3_ppo": sb3, "torchrl_ppo": torchrl}, SCENARIO, seeds, max_steps=max_steps)
    print(result)
    return result


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sb3-steps", type=int, default=4096)
    parser.add_argument("--torchrl-iterations", type=int, default=10)
    parser.add_argument("--torchrl-frames", type=int, default=256)
    parser.add_argument("--seeds", type=int, default=len(SEEDS), help="episodes per policy (seeds 1000, 1001, ...)")
    parser.add_argument("--max-steps", type=int, default=None, help="cut every episode here (default: 900)")
    args = parser.parse_args()
    main(args.sb3_steps, args.torchrl_iterations, args.torchrl_frames, list(range(1000, 1000 + args.seeds)),
         args.max_steps)
