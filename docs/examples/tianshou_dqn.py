"""A neural agent learns to prefer the high-value circuit, with Tianshou's DQN.

Robot 0 of `dahl2004` is the learner (`tavc_agents.envs.single_robot.SingleRobotEnv`: one step is one of its
tasks, the reward is the arena's `w / t`); the five other robots choose at random. Before training
the greedy network's choices are arbitrary; after training it serves the high-value circuit
(value 2200 against 2000; the crowding is the same on both under random co-workers).

Tianshou and PyTorch are heavy, optional dependencies, not part of any extra:

    pip install torch --index-url https://download.pytorch.org/whl/cpu
    pip install tianshou
    python docs/examples/tianshou_dqn.py            # about 2 minutes on one core

The test (`tests/test_examples.py::test_tianshou_dqn`, marker `marl`) runs only where Tianshou is
installed; its output, run once, is in `docs/examples/tianshou_dqn_output.txt`.
"""

from __future__ import annotations

import numpy as np
import torch
from tianshou.algorithm import DQN
from tianshou.algorithm.modelfree.dqn import DiscreteQLearningPolicy
from tianshou.algorithm.optim import AdamOptimizerFactory
from tianshou.data import Collector, VectorReplayBuffer
from tianshou.env import DummyVectorEnv
from tianshou.trainer import OffPolicyTrainerParams
from tianshou.utils.net.common import Net

from tavc_agents.allocators.baselines import RandomAllocator
from tavc_agents.envs.single_robot import SingleRobotEnv

# Rewards are w / t with t in milliseconds (about 0.02); scaled here so the network sees O(1).
REWARD_SCALE = 100.0


class Scaled(SingleRobotEnv):
    """Rewards scaled; infos kept to their plain numbers (Tianshou stores them in its replay
    buffer; the action mask, an array, is not needed there)."""

    def reset(self, *, seed=None, options=None):  # type: ignore[override]
        obs, info = super().reset(seed=seed, options=options)
        return obs, _numbers(info)

    def step(self, action: int):  # type: ignore[override]
        obs, reward, terminated, truncated, info = super().step(action)
        return obs, reward * REWARD_SCALE, terminated, truncated, _numbers(info)


def _numbers(info: dict) -> dict:
    return {k: v for k, v in info.items() if isinstance(v, (int, float)) and v is not None}


def make_env(episode_h: float = 2.0) -> Scaled:
    return Scaled(episode_s=episode_h * 3600.0, others=lambda agent: RandomAllocator())


def high_value_share(policy: DiscreteQLearningPolicy, seed: int, episodes: int = 2) -> float:
    """Fraction of the greedy policy's choices that are circuit 0 (the high-value one)."""
    env = make_env()
    chosen = []
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        done = False
        while not done:
            with torch.no_grad():
                q = policy.model(torch.as_tensor(obs[None], dtype=torch.float32))[0]
            action = int(torch.argmax(q[0]))
            chosen.append(action)
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
    return float(np.mean(np.array(chosen) == 0))


def train(seed: int = 0, epochs: int = 5, steps_per_epoch: int = 2000) -> dict[str, float]:
    torch.manual_seed(seed)
    np.random.seed(seed)
    train_envs = DummyVectorEnv([make_env for _ in range(4)])
    train_envs.seed(seed)
    net = Net(state_shape=2, action_shape=2, hidden_sizes=[32, 32])
    policy = DiscreteQLearningPolicy(
        model=net,
        action_space=make_env().action_space,
        eps_training=0.2,
        eps_inference=0.0,
    )
    algorithm = DQN(
        policy=policy,
        optim=AdamOptimizerFactory(lr=1e-3),
        gamma=0.9,
        target_update_freq=200,
    )
    before = high_value_share(policy, seed=1000)
    collector = Collector(
        algorithm, train_envs, VectorReplayBuffer(20_000, 4), exploration_noise=True
    )
    collector.reset()
    collector.collect(n_step=400, random=True)
    algorithm.run_training(
        OffPolicyTrainerParams(
            training_collector=collector,
            max_epochs=epochs,
            epoch_num_steps=steps_per_epoch,
            collection_step_num_env_steps=40,
            update_step_num_gradient_steps_per_sample=0.25,
            batch_size=64,
            test_in_training=False,
            verbose=False,
            show_progress=False,
        )
    )
    after = high_value_share(policy, seed=1000)
    return {"high_value_share_before": before, "high_value_share_after": after}


if __name__ == "__main__":
    print(train())
