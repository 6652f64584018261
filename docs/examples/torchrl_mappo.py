"""MAPPO on `dahl2004` with TorchRL: the arena through TorchRL's own `PettingZooWrapper`.

No wrapper of our own: `PettingZooWrapper(tavc_env.parallel_env(...))` builds the specs from the
env's spaces, the action mask from the observation's `action_mask`, and the infos as tensors.
The actor is one network shared by all robots (decentralised: each robot sees its own `paper_id`
observation); the critic is centralised (it sees every robot's observation), which is MAPPO.

    pip install "tavc-env[marl]"
    python docs/examples/torchrl_mappo.py --updates 2 --batch 200 --eval-every 1 --eval-hours 0.2 --out /tmp/mappo
    python docs/examples/torchrl_mappo.py --preset dahl2004 --out benchmarks/results/marl/torchrl_mappo_dahl2004

After every `--eval-every` batches the actor is exported (`tavc_agents.learners.network.Mlp`) and run
greedily on physics; `--out` gets the learning curve (CSV + PNG), the final evaluation on fresh
seeds and `network.npz`.
"""

from __future__ import annotations

import torch
import tyro
from torchrl.collectors import Collector
from torchrl.envs import TransformedEnv
from torchrl.modules import MultiAgentMLP, ProbabilisticActor
from torchrl.objectives import ClipPPOLoss

import tavc_env
from tavc_agents.learners import torchrl_ppo
from tavc_agents.learners.torchrl_ppo import network
from tavc_agents.learning_runs import (
    DEFAULT_OPTIONS,
    REWARD_SCALE,
    LearningRun,
    RunOptions,
    training_arena,
)

__all__ = ["make_env", "make_mappo", "network", "train"]


def make_env(seed: int, preset: str = "dahl2004") -> TransformedEnv:
    arena = tavc_env.parallel_env(**training_arena(preset))
    return torchrl_ppo.make_env(arena, seed, REWARD_SCALE)


def make_mappo(env: TransformedEnv) -> tuple[ProbabilisticActor, ClipPPOLoss, MultiAgentMLP]:
    """The shared actor, the centralised critic's loss and the actor's network (the package's
    `tavc_agents.learners.torchrl_ppo`, which the deep leaderboard trains with too)."""
    return torchrl_ppo.make_ppo(env, "mappo", gamma=0.9)


def train(
    updates: int = 100, batch: int = 1000, options: RunOptions = DEFAULT_OPTIONS
) -> LearningRun:
    """`updates` PPO updates, each on `batch` env steps (every robot's transition in each)."""
    torch.manual_seed(options.seed)
    torch.set_num_threads(1)
    env = make_env(options.seed, options.preset)
    actor, loss, actor_net = make_mappo(env)
    optimiser = torch.optim.Adam(loss.parameters(), 3e-4)
    run = options.start(
        "torchrl_mappo",
        "TorchRL MAPPO, shared actor, centralised critic",
        {"updates": updates, "batch": batch},
    )
    options.update_done(run, 0, updates, 0, lambda: network(actor_net))  # the untrained network
    collector = Collector(env, actor, frames_per_batch=batch, total_frames=updates * batch)
    for k, data in enumerate(collector, start=1):
        torchrl_ppo.update(loss, optimiser, data, epochs=4)
        collector.update_policy_weights_()
        options.update_done(run, k, updates, k * batch, lambda: network(actor_net))
    collector.shutdown()
    return options.finish(run)


if __name__ == "__main__":
    tyro.cli(train, config=(tyro.conf.OmitArgPrefixes,))
