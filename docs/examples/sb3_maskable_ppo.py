"""One MaskablePPO policy shared by the six robots of `dahl2004`, with Stable-Baselines3.

The package's `SharedPolicyVecEnv` makes every robot of every arena copy one slot of an SB3
`VecEnv` and hands MaskablePPO the action masks (PettingZoo's SuperSuit recipe cannot: its vector
env has no `env_method`). Observations are `paper_id`: the paper's one-hot of the last circuit and
the robot's index, so the shared network can tell robots apart.

    pip install "tavc-env[marl]"
    python docs/examples/sb3_maskable_ppo.py --steps 512 --chunks 2 --eval-hours 0.2 --out /tmp/sb3
    python docs/examples/sb3_maskable_ppo.py --out docs/examples/results/sb3_maskable_ppo

After each chunk of training the network is exported (`agents.learners.network.Mlp`) and run
greedily on physics; `--out` gets the learning curve (CSV + PNG), the final evaluation on fresh
seeds and `network.npz` (the allocator `network` in the allocator study).
"""

from __future__ import annotations

from pathlib import Path

import torch
import tyro
from sb3_contrib import MaskablePPO

from agents.learners.network import Mlp
from agents.studies.learning_runs import (
    REWARD_SCALE,
    LearningRun,
    training_arena,
    write_learning_run,
)
from tavc_env.adapters.sb3 import SharedPolicyVecEnv


def network(model: MaskablePPO) -> Mlp:
    """The policy's layers (SB3's MlpPolicy: two tanh layers, then the action head)."""
    hidden = [m for m in model.policy.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
    return Mlp.from_torch([*hidden, model.policy.action_net], activation="tanh")


def train(
    steps: int = 200_000,
    chunks: int = 10,
    seed: int = 0,
    eval_hours: float = 2.0,
    final_seeds: int = 10,
    preset: str = "dahl2004",
) -> LearningRun:
    """Train for `steps` env steps in `chunks`, evaluating the greedy network after each."""
    torch.manual_seed(seed)
    torch.set_num_threads(1)
    venv = SharedPolicyVecEnv(n_envs=2, reward_scale=REWARD_SCALE, **training_arena(preset))
    model = MaskablePPO(
        "MlpPolicy", venv, n_steps=128, batch_size=256, n_epochs=4, gamma=0.9, seed=seed, verbose=0
    )
    settings = {
        "preset": preset,
        "steps": steps,
        "chunks": chunks,
        "seed": seed,
        "eval_hours": eval_hours,
        "n_envs": 2,
    }
    run = LearningRun(
        "sb3_maskable_ppo",
        "SB3 MaskablePPO, one network for all robots",
        training_arena(preset),
        settings,
    )
    for k in range(1, chunks + 1):
        model.learn(total_timesteps=steps * venv.num_envs // chunks, reset_num_timesteps=False)
        run.checkpoint(k * steps // chunks, network(model), eval_hours, seed=10_000)
    run.finish(range(20_000, 20_000 + final_seeds), eval_hours)
    return run


def main(
    steps: int = 200_000,
    chunks: int = 10,
    seed: int = 0,
    eval_hours: float = 2.0,
    final_seeds: int = 10,
    preset: str = "dahl2004",
    out: Path = Path("sb3_maskable_ppo"),
) -> None:
    """Train, evaluate, and write the learning curve, the evaluation and the network to `out`."""
    run = train(steps, chunks, seed, eval_hours, final_seeds, preset)
    for path in write_learning_run(run, out):
        print(f"wrote {path}")


if __name__ == "__main__":
    tyro.cli(main)
