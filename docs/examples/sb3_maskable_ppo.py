"""One MaskablePPO policy shared by the six robots of `dahl2004`, with Stable-Baselines3.

The package's `SharedPolicyVecEnv` makes every robot of every arena copy one slot of an SB3
`VecEnv` and hands MaskablePPO the action masks (PettingZoo's SuperSuit recipe cannot: its vector
env has no `env_method`). Observations are `paper_id`: the paper's one-hot of the last circuit and
the robot's index, so the shared network can tell robots apart.

    pip install "tavc-env[marl]"
    python docs/examples/sb3_maskable_ppo.py --updates 2 --eval-every 1 --eval-hours 0.2 --out /tmp/sb3
    python docs/examples/sb3_maskable_ppo.py --preset dahl2004 --out benchmarks/results/marl/sb3_maskable_ppo_dahl2004

After every `--eval-every` updates the network is exported (`tavc_agents.learners.network.Mlp`) and run
greedily on physics; `--out` gets the learning curve (CSV + PNG), the final evaluation on fresh
seeds and `network.npz` (the allocator `network` in the allocator study).
"""

from __future__ import annotations

import torch
import tyro
from sb3_contrib import MaskablePPO

from tavc_agents.learners.network import Mlp
from tavc_agents.learning_runs import (
    DEFAULT_OPTIONS,
    REWARD_SCALE,
    LearningRun,
    RunOptions,
    training_arena,
)
from tavc_env.adapters.sb3 import SharedPolicyVecEnv


def network(model: MaskablePPO) -> Mlp:
    """The policy's layers (SB3's MlpPolicy: two tanh layers, then the action head)."""
    hidden = [m for m in model.policy.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
    return Mlp.from_torch([*hidden, model.policy.action_net], activation="tanh")


def train(updates: int = 100, options: RunOptions = DEFAULT_OPTIONS) -> LearningRun:
    """`updates` PPO updates, each on 128 env steps of two arena copies (1536 robot steps)."""
    torch.manual_seed(options.seed)
    torch.set_num_threads(1)
    venv = SharedPolicyVecEnv(n_envs=2, reward_scale=REWARD_SCALE, **training_arena(options.preset))
    model = MaskablePPO(
        "MlpPolicy", venv, n_steps=128, batch_size=256, n_epochs=4, gamma=0.9, seed=options.seed
    )
    run = options.start(
        "sb3_maskable_ppo",
        "SB3 MaskablePPO, one network for all robots",
        {"updates": updates, "n_steps": 128, "n_envs": 2},
    )
    options.update_done(run, 0, updates, 0, lambda: network(model))  # the untrained network
    for k in range(1, updates + 1):
        model.learn(total_timesteps=128 * venv.num_envs, reset_num_timesteps=False)
        options.update_done(run, k, updates, k * 128, lambda: network(model))
    return options.finish(run)


if __name__ == "__main__":
    tyro.cli(train, config=(tyro.conf.OmitArgPrefixes,))
