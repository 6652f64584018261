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

from types import SimpleNamespace

import torch
import tyro
from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector
from torchrl.envs import RewardScaling, TransformedEnv
from torchrl.envs.libs.pettingzoo import PettingZooWrapper
from torchrl.modules import MaskedCategorical, MultiAgentMLP, ProbabilisticActor
from torchrl.objectives import ClipPPOLoss, ValueEstimators

import tavc_env
from tavc_agents.learners.network import Mlp
from tavc_agents.learning_runs import (
    DEFAULT_OPTIONS,
    REWARD_SCALE,
    LearningRun,
    RunOptions,
    training_arena,
)

GROUP = "robot"  # TorchRL's default group of robot_0 .. robot_5
OBS = (GROUP, "observation", "observation")  # the Dict's vector; its mask is (GROUP, "action_mask")


def make_env(seed: int, preset: str = "dahl2004") -> TransformedEnv:
    env = PettingZooWrapper(
        tavc_env.parallel_env(**training_arena(preset)), categorical_actions=True, seed=seed
    )
    return TransformedEnv(env, RewardScaling(0.0, REWARD_SCALE, in_keys=[(GROUP, "reward")]))


def make_mappo(env: TransformedEnv) -> tuple[ProbabilisticActor, ClipPPOLoss, MultiAgentMLP]:
    n_robots = len(env.group_map[GROUP])
    n_obs = env.observation_spec[OBS].shape[-1]
    n_actions = env.full_action_spec[env.action_key].space.n

    def mlp(n_out: int, centralised: bool) -> MultiAgentMLP:
        return MultiAgentMLP(
            n_obs,
            n_out,
            n_agents=n_robots,
            centralised=centralised,
            share_params=True,
            depth=2,
            num_cells=64,
            activation_class=torch.nn.Tanh,
        )

    actor_net = mlp(n_actions, centralised=False)
    actor = ProbabilisticActor(
        TensorDictModule(actor_net, in_keys=[OBS], out_keys=[(GROUP, "logits")]),
        in_keys={"logits": (GROUP, "logits"), "mask": (GROUP, "action_mask")},
        out_keys=[env.action_key],
        distribution_class=MaskedCategorical,
        return_log_prob=True,
        log_prob_key=(GROUP, "sample_log_prob"),
    )
    critic = TensorDictModule(
        mlp(1, centralised=True), in_keys=[OBS], out_keys=[(GROUP, "state_value")]
    )
    loss = ClipPPOLoss(
        actor,
        critic,
        entropy_coeff=0.01,
        normalize_advantage=True,
        normalize_advantage_exclude_dims=(-2,),  # per robot, not across the group
    )
    loss.set_keys(
        reward=(GROUP, "reward"),
        action=env.action_key,
        value=(GROUP, "state_value"),
        sample_log_prob=(GROUP, "sample_log_prob"),
        done=(GROUP, "done"),
        terminated=(GROUP, "terminated"),
    )
    loss.make_value_estimator(ValueEstimators.GAE, gamma=0.9, lmbda=0.95)
    return actor, loss, actor_net


def network(actor_net: MultiAgentMLP) -> Mlp:
    """The shared actor's layers (its parameters: one set, as `share_params=True`)."""
    params = actor_net.params
    keys = sorted(params.keys(), key=int)
    return Mlp.from_torch([SimpleNamespace(**params[k]) for k in keys], activation="tanh")


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
        with torch.no_grad():
            loss.value_estimator(
                data,
                params=loss.critic_network_params,
                target_params=loss.target_critic_network_params,
            )
        for _ in range(4):
            out = loss(data)
            total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
            optimiser.zero_grad()
            total.backward()
            torch.nn.utils.clip_grad_norm_(loss.parameters(), 1.0)
            optimiser.step()
        collector.update_policy_weights_()
        options.update_done(run, k, updates, k * batch, lambda: network(actor_net))
    collector.shutdown()
    return options.finish(run)


if __name__ == "__main__":
    tyro.cli(train, config=(tyro.conf.OmitArgPrefixes,))
