"""PPO with one actor shared by every robot, through TorchRL's own `PettingZooWrapper`: MAPPO (a
centralised critic, which sees every robot's observation) and IPPO (a decentralised critic, shared
too), as TorchRL's multi-agent tutorials build them. Needs the `marl` extra (torch, TorchRL).

`make_env` wraps a scenario's env as it is (`paper_id` observations, so the shared actor tells the
robots apart), each robot credited with its own rewards or with the team's (`CREDITS`);
`make_ppo` builds the actor, the critic and the loss; `network` exports the actor for the trial
runner (`tavc_agents.learners.network.Mlp`); `train` runs PPO until a budget of decisions is
spent. A decision is one robot's action at its decision epoch (docs/semi_mdp.md): a
robot not at an epoch has a mask that allows only its own circuit, so its action is forced, its
log-probability is 0 and it adds nothing to the policy's gradient.
"""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import torch
from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector
from torchrl.envs import Compose, RewardScaling, Transform, TransformedEnv
from torchrl.envs.libs.pettingzoo import PettingZooWrapper
from torchrl.modules import MaskedCategorical, MultiAgentMLP, ProbabilisticActor
from torchrl.objectives import ClipPPOLoss, ValueEstimators

from tavc_agents.learners.network import Mlp
from tavc_env.validation import require

GROUP = "robot"  # TorchRL's default group of robot_0 .. robot_{n-1}
OBS = (GROUP, "observation", "observation")  # the Dict's vector; its mask is (GROUP, "action_mask")
MASK = (GROUP, "action_mask")
ALGORITHMS = ("mappo", "ippo")
"""mappo: the critic sees every robot's observation; ippo: each robot's own (both shared)."""
CREDITS = ("own", "team")
"""own: each robot's reward is its own deliveries; team: every robot gets the team's mean reward
of the step (docs/semi_mdp.md section 4: the team's objective, at the cost of noise)."""


class TeamReward(Transform):
    """Every robot's reward replaced by the mean over the group in the same step."""

    def __init__(self) -> None:
        super().__init__(in_keys=[(GROUP, "reward")], out_keys=[(GROUP, "reward")])

    def _apply_transform(self, reward: torch.Tensor) -> torch.Tensor:
        return reward.mean(dim=-2, keepdim=True).expand_as(reward)  # (..., robots, 1)

    def transform_reward_spec(self, reward_spec: Any) -> Any:
        return reward_spec


def make_env(
    parallel_env: Any, seed: int, reward_scale: float, credit: str = "own"
) -> TransformedEnv:
    """`parallel_env` (a PettingZoo ParallelEnv with `paper_id` observations) in TorchRL's
    wrapper, seeded with `seed`, its rewards credited as `credit` says and multiplied by
    `reward_scale` (networks see O(1))."""
    require(credit in CREDITS, "credit", credit, f"one of {list(CREDITS)}")
    env = PettingZooWrapper(parallel_env, categorical_actions=True, seed=seed)
    scale = RewardScaling(0.0, reward_scale, in_keys=[(GROUP, "reward")])
    return TransformedEnv(env, Compose(TeamReward(), scale) if credit == "team" else scale)


def make_ppo(
    env: TransformedEnv, algorithm: str, gamma: float = 0.99, lmbda: float = 0.95
) -> tuple[ProbabilisticActor, ClipPPOLoss, MultiAgentMLP]:
    """The shared actor, the loss (its critic: centralised for `mappo`) and the actor's network.
    `gamma` discounts per env step (event-driven: about one decision each)."""
    require(algorithm in ALGORITHMS, "algorithm", algorithm, f"one of {list(ALGORITHMS)}")
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
        in_keys={"logits": (GROUP, "logits"), "mask": MASK},
        out_keys=[env.action_key],
        distribution_class=MaskedCategorical,
        return_log_prob=True,
        log_prob_key=(GROUP, "sample_log_prob"),
    )
    critic = TensorDictModule(
        mlp(1, centralised=algorithm == "mappo"), in_keys=[OBS], out_keys=[(GROUP, "state_value")]
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
    loss.make_value_estimator(ValueEstimators.GAE, gamma=gamma, lmbda=lmbda)
    return actor, loss, actor_net


def network(actor_net: MultiAgentMLP) -> Mlp:
    """The shared actor's layers (its parameters: one set, as `share_params=True`)."""
    params = actor_net.params
    keys = sorted(params.keys(), key=int)
    return Mlp.from_torch([SimpleNamespace(**params[k]) for k in keys], activation="tanh")


def decisions_in(data: Any) -> int:
    """The robots' decisions in a batch: the rows whose mask allows every circuit."""
    return int(data[MASK].all(-1).sum().item())


def update(loss: ClipPPOLoss, optimiser: Any, data: Any, epochs: int) -> None:
    """One PPO update on a batch: GAE from the critic, then `epochs` clipped passes."""
    with torch.no_grad():
        loss.value_estimator(
            data,
            params=loss.critic_network_params,
            target_params=loss.target_critic_network_params,
        )
    for _ in range(epochs):
        out = loss(data)
        total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
        optimiser.zero_grad()
        total.backward()
        torch.nn.utils.clip_grad_norm_(loss.parameters(), 1.0)
        optimiser.step()


def train(
    env: TransformedEnv,
    algorithm: str,
    decisions: int,
    batch: int,
    on_batch: Callable[[int, int, Callable[[], Mlp]], None],
    *,
    epochs: int = 4,
    lr: float = 3e-4,
) -> tuple[Mlp, int, int]:
    """PPO until `decisions` robot decisions are collected, in batches of `batch` env steps, each
    used for `epochs` passes. Before the first batch and after every batch `on_batch(decisions so
    far, env steps so far, network)` (the network exported on demand). Returns the final network, the decisions and the
    env steps taken. The caller seeds torch and env."""
    require(decisions >= 1, "decisions", decisions, ">= 1")
    require(batch >= 2, "batch", batch, ">= 2 env steps")
    actor, loss, actor_net = make_ppo(env, algorithm)
    optimiser = torch.optim.Adam(loss.parameters(), lr)
    collector = Collector(env, actor, frames_per_batch=batch, total_frames=-1)
    done = steps = 0
    on_batch(0, 0, lambda: network(actor_net))  # the untrained network
    try:
        for data in collector:
            done += decisions_in(data)
            steps += batch
            update(loss, optimiser, data, epochs)
            collector.update_policy_weights_()
            on_batch(done, steps, lambda: network(actor_net))
            if done >= decisions:
                break
    finally:
        collector.shutdown()
    return network(actor_net), done, steps
