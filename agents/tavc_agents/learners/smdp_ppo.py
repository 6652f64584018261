"""PPO that follows the semi-MDP contract (docs/semi_mdp.md), on TorchRL's own parts: the batched
env `tavc_env.adapters.torchrl_env.TorchArenaEnv`, a `Collector`, a `ProbabilisticActor` with a
`MaskedCategorical` and `ClipPPOLoss`. Needs the `marl` extra (torch, TorchRL).

What makes it the contract's:

- **Returns per robot, per decision.** A robot's decision rows form its own sequence; decision
  j earns R_j, its rewards summed until its next decision epoch, and is discounted by
  gamma_h ** (tau_j / 3600), tau_j its sojourn (`elapsed_s` at that epoch) and gamma_h one number
  per simulated hour, the same meaning in every scenario (`smdp_gae`). GAE(lambda) runs over
  that sequence. A time limit is not a terminal state: a robot that delivered in the last step
  bootstraps from the value of its final observation; one still on its task has no outcome and
  its decision is dropped. So is a decision whose next epoch falls after the end of the batch
  (about n_robots / steps_per_batch of the decisions; the decision before it bootstraps there).
- **Decisions only.** Only decision rows with an outcome enter the loss and the advantage
  normalisation: they are gathered from the batch before the update, so busy robots' rows
  cost nothing either.
- **MAPPO's critic reads `state()`** (the arena's global state, with one value head per robot);
  IPPO's reads the robot's own observation.
- **Parameters** `shared` (default: one actor for all, which tells robots apart by the
  `paper_id` observation), `class` (one set per speed class: robots of one nominal speed share
  it) or `robot` (one set each). Per-class sets are separate parameters selected by the robot's
  `index` (`ParameterSets`), not TorchRL groups: a group would need every robot's row in every
  sample, and the update sees decision rows only.

The ablations of the deep-learners issue are settings of the same code: `discount="step"`
(gamma per env step, the old route's), `rows="all"` (every row a transition of one env step, busy
rows in the loss with their forced mask).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector
from torchrl.modules import MLP, MaskedCategorical, ProbabilisticActor
from torchrl.objectives import ClipPPOLoss

from tavc_agents.learners.network import Mlp, NetworkSet
from tavc_env.adapters.torchrl_env import GROUP, TorchArenaEnv
from tavc_env.validation import is_integer, is_number, require

ALGORITHMS = ("mappo", "ippo")
PARAMETERS = ("shared", "class", "robot")
DISCOUNTS = ("time", "step")
ROWS = ("decisions", "all")
CREDITS = ("own", "team")
OBS, MASK, INDEX = (GROUP, "observation"), (GROUP, "action_mask"), (GROUP, "index")
ACTION, LOG_PROB, VALUE = (GROUP, "action"), (GROUP, "sample_log_prob"), (GROUP, "state_value")


@dataclass(frozen=True, kw_only=True)
class PpoSettings:
    """Every setting of a run, checked when made."""

    algorithm: str = "mappo"
    """mappo: critic on each arena's `state()`; ippo: on each robot's own observation"""
    parameters: str = "shared"
    """shared, class (one set per speed class) or robot (one set per robot): actor and IPPO critic"""
    discount: str = "time"
    """time: gamma_h ** (tau / 3600) per decision (the contract); step: gamma_step per env step"""
    rows: str = "decisions"
    """decisions: decision rows only (the contract); all: every robot's row of every env step"""
    credit: str = "own"
    """own: each robot's rewards; team: the team's mean reward of each step, every robot alike"""
    gamma_h: float = 0.1
    """discount per simulated hour (0.1: about 0.95 over an 80-s task)"""
    gamma_step: float = 0.99
    """discount per env step (`discount="step"` only)"""
    lmbda: float = 0.95
    n_envs: int = 16
    """arenas stepped together (the env's batch size K)"""
    steps_per_batch: int = 256
    """env steps per arena per batch"""
    epochs: int = 4
    minibatch: int = 1024
    """rows per gradient step"""
    lr: float = 3e-4
    clip: float = 0.2
    entropy: float = 0.01
    hidden: int = 64
    """units in each of the two hidden layers (tanh)"""
    reward_scale: float = 1e-3
    """rewards are multiplied by it (value rewards are about 2000 a delivery)"""
    max_grad_norm: float = 1.0

    def __post_init__(self) -> None:
        for name, allowed in (
            ("algorithm", ALGORITHMS),
            ("parameters", PARAMETERS),
            ("discount", DISCOUNTS),
            ("rows", ROWS),
            ("credit", CREDITS),
        ):
            value = getattr(self, name)
            require(value in allowed, name, value, f"one of {list(allowed)}")
        for name in ("gamma_h", "gamma_step", "lmbda"):
            value = getattr(self, name)
            require(is_number(value) and 0 < value <= 1, name, value, "a number in (0, 1]")
        for name in ("n_envs", "steps_per_batch", "epochs", "minibatch", "hidden"):
            value = getattr(self, name)
            require(is_integer(value) and value >= 1, name, value, "an integer >= 1")
        for name in ("lr", "clip", "reward_scale", "max_grad_norm"):
            value = getattr(self, name)
            require(is_number(value) and value > 0, name, value, "a number > 0")
        require(is_number(self.entropy) and self.entropy >= 0, "entropy", self.entropy, ">= 0")

    def as_record(self) -> dict[str, Any]:
        return asdict(self)


def make_env(s: PpoSettings, seed: int, **env_kwargs: Any) -> TorchArenaEnv:
    """The batched env a run of `s` trains on: `s.n_envs` arenas of `env_kwargs` (arguments of
    `tavc_env.arena.make_env`: a `scenario`, `max_sim_time_s`, ...) with value rewards (the
    contract's), each arena's `state()` only where MAPPO's critic reads it, seeded from `seed`."""
    return TorchArenaEnv(
        s.n_envs,
        env_kwargs={"reward": "value", **env_kwargs},
        seed=seed,
        with_state=s.algorithm == "mappo",
    )


# -- the semi-MDP advantages ------------------------------------------------------------------------
def smdp_gae(
    reward: torch.Tensor,
    value: torch.Tensor,
    next_value: torch.Tensor,
    decides: torch.Tensor,
    next_epoch: torch.Tensor,
    done: torch.Tensor,
    discount: torch.Tensor,
    step_discount: torch.Tensor,
    lmbda: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """GAE(lambda) over each robot's own decisions, for a batch of `T` env steps laid out
    `(..., T, n)` (time then robot; leading dims: arenas): returns the advantage of every decision
    row and which rows have one (a decision with an outcome in the batch).

    Row t holds a robot's observation (a decision row if `decides`), its `value`, the `reward`
    it got in step t and what follows the step: `next_epoch` (the observation after the step is
    its decision epoch), `next_value` (the value there), `done` (the episode ended in the step,
    a time limit: bootstrap, not a terminal state), `discount` (the discount of a sojourn that
    ends at that epoch: gamma ** tau) and `step_discount` (multiplied in for each step the sojourn
    lasts beyond its last one: 1 when discounting by time, gamma_step when by step).

    Decision j (at row t) earns R_j = rewards of steps t .. t'-1 (t' its next epoch) and has
    delta_j = R_j + d_j V_{j+1} - V_j and A_j = delta_j + d_j lambda A_{j+1}, with A_{j+1} = 0
    where the next decision's own outcome is not in the batch or the episode ended."""
    T = reward.shape[-2]
    zeros = torch.zeros_like(reward[..., 0, :])
    acc, disc, nxt_v, nxt_a = zeros.clone(), zeros.clone(), zeros.clone(), zeros.clone()
    pending = torch.zeros_like(decides[..., 0, :])  # a later epoch is known for the decision
    advantage = torch.zeros_like(reward)
    has = torch.zeros_like(decides)
    for t in range(T - 1, -1, -1):
        epoch, ended = next_epoch[..., t, :], done[..., t, :]
        inside = epoch & ~ended & (t + 1 < T)  # the next epoch is row t + 1, in the batch
        nxt_v = torch.where(epoch, value[..., t + 1, :] if t + 1 < T else zeros, nxt_v)
        nxt_v = torch.where(epoch & ~inside, next_value[..., t, :], nxt_v)
        nxt_a = torch.where(inside, advantage[..., t + 1, :] if t + 1 < T else zeros, nxt_a)
        nxt_a = torch.where(epoch & ~inside, zeros, nxt_a)
        pending = torch.where(epoch, True, torch.where(ended, False, pending))
        acc = torch.where(epoch | ended, zeros, acc) + reward[..., t, :]
        disc = torch.where(epoch, discount[..., t, :], disc * step_discount[..., t, :])
        row = decides[..., t, :] & pending
        delta = acc + disc * nxt_v - value[..., t, :]
        advantage[..., t, :] = torch.where(row, delta + disc * lmbda * nxt_a, zeros)
        has[..., t, :] = row
    return advantage, has


def discounts(next_elapsed: torch.Tensor, s: PpoSettings) -> tuple[torch.Tensor, torch.Tensor]:
    """`smdp_gae`'s `discount` and `step_discount` for sojourns ending with `next_elapsed`
    seconds: gamma_h ** (tau / 3600) and 1 (`discount="time"`), or gamma_step for each step."""
    if s.discount == "time":
        discount = torch.pow(s.gamma_h, next_elapsed / 3600.0)
        return discount, torch.ones_like(discount)
    step = torch.full_like(next_elapsed, s.gamma_step)
    return step, step


# -- the networks -----------------------------------------------------------------------------------
class ParameterSets(torch.nn.Module):
    """`len(set(group_of))` MLPs (two tanh hidden layers); robot `i`'s rows go through MLP
    `group_of[i]`. One group is plain sharing."""

    def __init__(self, n_in: int, n_out: int, group_of: Sequence[int], hidden: int) -> None:
        super().__init__()
        groups = sorted(set(group_of))
        require(groups == list(range(len(groups))), "group_of", group_of, "groups 0, 1, ...")
        self.mlps = torch.nn.ModuleList(
            MLP(n_in, n_out, depth=2, num_cells=hidden, activation_class=torch.nn.Tanh)
            for _ in groups
        )
        self.register_buffer("group_of", torch.as_tensor(list(group_of), dtype=torch.int64))
        self.n_out = n_out

    def forward(self, x: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
        if len(self.mlps) == 1:
            out: torch.Tensor = self.mlps[0](x)
            return out
        group = self.group_of[index]
        out = x.new_zeros((*x.shape[:-1], self.n_out))
        for g, mlp in enumerate(self.mlps):
            rows = group == g
            out[rows] = mlp(x[rows])
        return out


class StateCritic(torch.nn.Module):
    """MAPPO's critic: each arena's `state()` in, one value per robot out; a row takes its
    robot's (`index`)."""

    def __init__(self, n_state: int, n_robots: int, hidden: int) -> None:
        super().__init__()
        self.mlp = MLP(n_state, n_robots, depth=2, num_cells=hidden, activation_class=torch.nn.Tanh)

    def forward(self, state: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
        values: torch.Tensor = self.mlp(state)
        if index.dim() == state.dim():  # rows of (arena, robot): state broadcast over robots
            return values.gather(-1, index).unsqueeze(-1)
        return values.gather(-1, index.unsqueeze(-1))


def groups_of(env: TorchArenaEnv, parameters: str) -> list[int]:
    """Each robot's parameter set: all one (`shared`), by nominal speed (`class`), its own
    (`robot`)."""
    speeds = [robot.speed for robot in env.config.robots]
    if parameters == "shared":
        return [0] * len(speeds)
    if parameters == "robot":
        return list(range(len(speeds)))
    classes = sorted(set(speeds))
    return [classes.index(s) for s in speeds]


@dataclass
class Learner:
    """The actor, the critic and the loss of a run."""

    actor: ProbabilisticActor
    critic: TensorDictModule
    loss: ClipPPOLoss
    actor_net: ParameterSets


def make_learner(env: TorchArenaEnv, s: PpoSettings) -> Learner:
    width = int(env.observation_spec[OBS].shape[-1])
    groups = groups_of(env, s.parameters)
    actor_net = ParameterSets(width, env.n_circuits, groups, s.hidden)
    actor = ProbabilisticActor(
        TensorDictModule(actor_net, in_keys=[OBS, INDEX], out_keys=[(GROUP, "logits")]),
        in_keys={"logits": (GROUP, "logits"), "mask": MASK},
        out_keys=[ACTION],
        distribution_class=MaskedCategorical,
        return_log_prob=True,
        log_prob_key=LOG_PROB,
    )
    if s.algorithm == "mappo":
        n_state = int(env.observation_spec["state"].shape[-1])
        net: torch.nn.Module = StateCritic(n_state, env.n_robots, s.hidden)
        critic = TensorDictModule(net, in_keys=["state", INDEX], out_keys=[VALUE])
    else:
        net = ParameterSets(width, 1, groups, s.hidden)
        critic = TensorDictModule(net, in_keys=[OBS, INDEX], out_keys=[VALUE])
    loss = ClipPPOLoss(
        actor,
        critic,
        clip_epsilon=s.clip,
        entropy_coeff=s.entropy,
        normalize_advantage=True,  # over a minibatch of the rows trained on
    )
    loss.set_keys(action=ACTION, sample_log_prob=LOG_PROB, value=VALUE)
    return Learner(actor, critic, loss, actor_net)


def network(actor_net: ParameterSets) -> NetworkSet:
    """The actor as the package's numpy networks: one for every robot (`shared`), or each set
    with the set of each robot (`class`, `robot`)."""
    mlps = tuple(
        Mlp.from_torch([m for m in mlp.modules() if isinstance(m, torch.nn.Linear)], "tanh")
        for mlp in actor_net.mlps
    )
    group_of = tuple(int(g) for g in actor_net.group_of.tolist())
    return NetworkSet(mlps, None if len(mlps) == 1 else group_of)


# -- a batch: advantages, then the rows trained on ----------------------------------------------------
def training_rows(data: TensorDictBase, learner: Learner, s: PpoSettings) -> TensorDictBase:
    """The batch `(K, T)` from the collector as the flat rows PPO trains on, each with its
    advantage and value target (`smdp_gae`)."""
    robots, after = data[GROUP], data["next"]
    n = robots.batch_size[-1]
    reward = after[GROUP, "reward"][..., 0] * s.reward_scale
    if s.credit == "team":
        reward = reward.mean(-1, keepdim=True).expand_as(reward)
    done = after["done"].expand(*after["done"].shape[:-1], n)
    elapsed, next_elapsed = robots["elapsed_s"][..., 0], after[GROUP, "elapsed_s"][..., 0]
    decides, next_epoch = robots["decides"], after[GROUP, "epoch"]
    if s.rows == "all":  # every row a transition of one env step: its sojourn is the step
        step_s = next_elapsed - torch.where(decides, torch.zeros_like(elapsed), elapsed)
        decides, next_epoch, next_elapsed = torch.ones_like(decides), torch.ones_like(done), step_s
    with torch.no_grad():
        value = learner.critic(data.select("state", OBS, INDEX, strict=False))[VALUE][..., 0]
        next_in = after.select("state", OBS, INDEX, strict=False)
        next_value = learner.critic(next_in)[VALUE][..., 0]
    advantage, rows = smdp_gae(
        reward, value, next_value, decides, next_epoch, done, *discounts(next_elapsed, s), s.lmbda
    )
    flat = {
        "advantage": advantage[rows].unsqueeze(-1),
        "value_target": (advantage + value)[rows].unsqueeze(-1),
        GROUP: TensorDict(
            {key: robots[key][rows] for key in ("observation", "action_mask", "index", "action")}
            | {"sample_log_prob": robots["sample_log_prob"][rows]},
            batch_size=[int(rows.sum())],
        ),
    }
    if "state" in data:
        flat["state"] = data["state"].unsqueeze(-2).expand(*rows.shape, -1)[rows]
    return TensorDict(flat, batch_size=[int(rows.sum())])


def update(
    learner: Learner, optimiser: torch.optim.Optimizer, rows: TensorDictBase, s: PpoSettings
) -> None:
    """`epochs` passes of clipped PPO over `rows`, in shuffled minibatches."""
    loss = learner.loss
    for _ in range(s.epochs):
        for part in torch.randperm(len(rows)).split(s.minibatch):
            out = loss(rows[part])
            total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
            optimiser.zero_grad()
            total.backward()
            torch.nn.utils.clip_grad_norm_(loss.parameters(), s.max_grad_norm)
            optimiser.step()


@dataclass(frozen=True)
class Progress:
    """After a batch: the robots' decisions and the env steps (per arena, summed) so far, and
    the CPU seconds of collection and of updates so far."""

    decisions: int
    steps: int
    collect_cpu_s: float
    update_cpu_s: float


def train(
    env: TorchArenaEnv,
    s: PpoSettings,
    decisions: int,
    on_batch: Callable[[Progress, Learner], None] | None = None,
) -> tuple[Learner, Progress]:
    """PPO on `env` until its robots took `decisions` decisions; `on_batch` after every batch. The caller seeds torch and the env (`TorchArenaEnv(seed=...)`)."""
    require(is_integer(decisions) and decisions >= 1, "decisions", decisions, "an integer >= 1")
    require(
        env.batch_size[0] == s.n_envs,
        "env",
        f"a batch of {env.batch_size[0]} arenas",
        f"n_envs = {s.n_envs} arenas (PpoSettings.n_envs)",
    )
    learner = make_learner(env, s)
    optimiser = torch.optim.Adam(learner.loss.parameters(), s.lr)
    collector = Collector(
        env,
        learner.actor,
        frames_per_batch=s.n_envs * s.steps_per_batch,
        total_frames=-1,
        auto_register_policy_transforms=False,  # the actor needs no recurrent-state tracker
    )
    done = steps = 0
    collect = update_cpu = 0.0
    clock = time.process_time()
    progress = Progress(0, 0, 0.0, 0.0)
    try:
        for data in collector:
            now = time.process_time()
            collect += now - clock
            rows = training_rows(data, learner, s)
            update(learner, optimiser, rows, s)
            collector.update_policy_weights_()
            clock = time.process_time()
            update_cpu += clock - now
            done += decisions_in(data)
            steps += s.n_envs * s.steps_per_batch
            progress = Progress(done, steps, collect, update_cpu)
            if on_batch is not None:
                on_batch(progress, learner)
                clock = time.process_time()
            if done >= decisions:
                break
    finally:
        collector.shutdown()
    return learner, progress


def decisions_in(data: TensorDictBase) -> int:
    """The robots' decisions in a batch (rows at which a robot decides)."""
    return int(data[GROUP, "decides"].sum())
