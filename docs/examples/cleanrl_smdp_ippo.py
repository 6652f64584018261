"""IPPO with one shared network, CleanRL-style in one file, following the semi-MDP contract.

The contract (docs/semi_mdp.md): only robots whose info says `action_required` act; the reward a
robot is paid at its next decision epoch is credited to the decision before it; `elapsed_s` there
is the transition's sojourn time tau, and advantages and returns discount by gamma ** tau (gamma
per simulated second); with `reward="value"` a robot's undiscounted return is the value it
delivered, so the team's summed return per hour is the evaluation metric, delivered value per
simulated hour. The learner drives the plain PettingZoo parallel API and nothing else.

Only PyTorch beyond the package:

    pip install torch --index-url https://download.pytorch.org/whl/cpu
    python docs/examples/cleanrl_smdp_ippo.py --total-hours 2 --rollout-hours 1 --eval-hours 0.5
    python docs/examples/cleanrl_smdp_ippo.py --help

It ends with a table of the metric on fixed evaluation seeds, for the trained network (greedy and
sampled) beside `random`, `stay` and, where the package ships the arena's TAVC model, the static
model optimum, all run by the package's trial runner. Output of a run:
docs/examples/cleanrl_smdp_ippo_output.txt.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
import tyro
from torch import nn

import tavc_env
from tavc_agents.allocators.baselines import RandomAllocator, StayAllocator
from tavc_agents.allocators.teams import StaticAllocator
from tavc_agents.experiments.runner import TrialResult, run_trial
from tavc_agents.model import load_model, missing_model
from tavc_env.validation import is_number, require


@dataclass(frozen=True)
class Settings:
    """What one run does (every field a command-line flag: --total-hours, --credit, ...)."""

    preset: str = "dahl2004"
    seed: int = 0
    total_hours: float = 1000.0
    """simulated hours of training, in episodes of `rollout_hours` (one PPO update each)"""
    rollout_hours: float = 2.0
    observation_mode: Literal["paper", "paper_id", "rich"] = "paper_id"
    credit: Literal["own", "team"] = "own"
    """own: a decision earns its robot's delivery (the env's credit); team: every delivery in
    its sojourn, divided by the team size (the metric's credit, noisier)"""
    gamma_per_hour: float = 0.1
    """discount per simulated hour (0.1: about 0.95 per 80-s task, the paper's per-task gamma)"""
    gae_lambda: float = 0.95
    learning_rate: float = 2.5e-4
    update_epochs: int = 4
    minibatches: int = 4
    clip_coef: float = 0.2
    ent_coef: float = 0.01
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden: int = 64
    eval_seeds: tuple[int, ...] = (10_000, 10_001, 10_002, 10_003, 10_004)
    eval_hours: float = 2.0
    out: Path | None = None
    """if given, the final table is written there (Markdown)"""

    def __post_init__(self) -> None:
        for name in ("total_hours", "rollout_hours", "learning_rate", "eval_hours"):
            value = getattr(self, name)
            require(is_number(value) and value > 0, name, value, "a finite number > 0")
        require(
            self.rollout_hours <= self.total_hours,
            "rollout_hours",
            self.rollout_hours,
            f"at most total_hours = {self.total_hours}",
        )
        for name in ("gamma_per_hour", "gae_lambda"):
            value = getattr(self, name)
            require(is_number(value) and 0 < value <= 1, name, value, "a number in (0, 1]")
        for name in ("update_epochs", "minibatches", "hidden"):
            value = getattr(self, name)
            require(isinstance(value, int) and value >= 1, name, value, "an integer >= 1")
        require(len(self.eval_seeds) >= 1, "eval_seeds", self.eval_seeds, "at least one seed")


def layer(n_in: int, n_out: int, std: float = float(np.sqrt(2))) -> nn.Linear:
    linear = nn.Linear(n_in, n_out)
    nn.init.orthogonal_(linear.weight, std)
    nn.init.constant_(linear.bias, 0.0)
    return linear


class Agent(nn.Module):
    """Actor and critic, shared by every robot (parameter sharing)."""

    def __init__(self, n_obs: int, n_actions: int, hidden: int) -> None:
        super().__init__()
        self.critic = nn.Sequential(
            layer(n_obs, hidden), nn.Tanh(), layer(hidden, hidden), nn.Tanh(), layer(hidden, 1, 1.0)
        )
        self.actor = nn.Sequential(
            layer(n_obs, hidden),
            nn.Tanh(),
            layer(hidden, hidden),
            nn.Tanh(),
            layer(hidden, n_actions, 0.01),
        )

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def dist(self, x: torch.Tensor, mask: torch.Tensor) -> torch.distributions.Categorical:
        logits = self.actor(x).masked_fill(~mask, -1e9)
        return torch.distributions.Categorical(logits=logits)


@dataclass
class Transition:
    """One decision of one robot: what it saw and chose, what that earned by its next decision
    epoch, and the simulated seconds in between."""

    obs: np.ndarray
    mask: np.ndarray
    action: int
    logprob: float
    value: float
    reward: float = 0.0
    tau_s: float = 0.0
    next_value: float = 0.0  # V at the next decision epoch (the time limit is no terminal)


def rollout(
    env: Any, agent: Agent, seed: int, settings: Settings, scale: float
) -> tuple[dict[str, list[Transition]], float]:
    """One episode: each robot's complete transitions, in order, and the delivered value per
    hour."""
    obs, infos = env.reset(seed=seed)
    pending: dict[str, Transition] = {}
    done: dict[str, list[Transition]] = {a: [] for a in env.possible_agents}
    delivered = 0.0
    while env.agents:
        deciders = [a for a in env.agents if infos[a]["action_required"]]
        actions: dict[str, int] = {}
        if deciders:
            x = torch.as_tensor(np.stack([obs[a]["observation"] for a in deciders]))
            m = torch.as_tensor(np.stack([obs[a]["action_mask"] for a in deciders]) > 0)
            with torch.no_grad():
                dist = agent.dist(x, m)
                chosen = dist.sample()
                logprobs = dist.log_prob(chosen)
                values = agent.value(x)
            for k, a in enumerate(deciders):
                actions[a] = int(chosen[k])
                pending[a] = Transition(
                    x[k].numpy(), m[k].numpy(), actions[a], float(logprobs[k]), float(values[k])
                )
        obs, rewards, _, truncations, infos = env.step(actions)
        team = sum(rewards.values())
        delivered += team
        for a, transition in pending.items():
            transition.reward += team / len(rewards) if settings.credit == "team" else rewards[a]
        # a decision epoch (a delivery at truncation is one too): the transition is complete
        ended = [a for a in infos if infos[a]["action_required"] or infos[a]["task_completed"]]
        for a in ended:
            transition = pending.pop(a)
            transition.reward /= scale
            transition.tau_s = infos[a]["elapsed_s"]
            x = torch.as_tensor(np.array(obs[a]["observation"])[None])
            with torch.no_grad():
                transition.next_value = float(agent.value(x)[0])
            done[a].append(transition)
        # at truncation a robot still on its task has no outcome yet: its pending decision is
        # dropped, and its last complete transition bootstrapped from the epoch that began it
        if any(truncations.values()):
            pending.clear()
    return done, delivered / (env.sim_time_s / 3600.0)


def advantages(
    trajectories: dict[str, list[Transition]], gamma_s: float, lam: float
) -> list[tuple[Transition, float]]:
    """GAE over each robot's own sequence of decisions, discounting each by gamma ** tau."""
    out = []
    for sequence in trajectories.values():
        running = 0.0
        for t in reversed(sequence):
            discount = gamma_s**t.tau_s
            delta = t.reward + discount * t.next_value - t.value
            running = delta + discount * lam * running
            out.append((t, running))
    return out


def update(
    agent: Agent,
    optimizer: torch.optim.Optimizer,
    batch: list[tuple[Transition, float]],
    settings: Settings,
    rng: np.random.Generator,
) -> dict[str, float]:
    obs = torch.as_tensor(np.stack([t.obs for t, _ in batch]))
    mask = torch.as_tensor(np.stack([t.mask for t, _ in batch]))
    actions = torch.as_tensor([t.action for t, _ in batch])
    old_logprob = torch.as_tensor([t.logprob for t, _ in batch])
    adv = torch.as_tensor([a for _, a in batch], dtype=torch.float32)
    returns = adv + torch.as_tensor([t.value for t, _ in batch])
    stats: dict[str, float] = {}
    for _ in range(settings.update_epochs):
        for idx in np.array_split(rng.permutation(len(batch)), settings.minibatches):
            if len(idx) == 0:
                continue
            i = torch.as_tensor(idx)
            dist = agent.dist(obs[i], mask[i])
            ratio = (dist.log_prob(actions[i]) - old_logprob[i]).exp()
            a = adv[i]
            a = (a - a.mean()) / (a.std() + 1e-8) if len(idx) > 1 else a
            pg_loss = torch.max(
                -a * ratio, -a * ratio.clamp(1 - settings.clip_coef, 1 + settings.clip_coef)
            ).mean()
            v_loss = 0.5 * ((agent.value(obs[i]) - returns[i]) ** 2).mean()
            entropy = dist.entropy().mean()
            loss = pg_loss - settings.ent_coef * entropy + settings.vf_coef * v_loss
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(agent.parameters(), settings.max_grad_norm)
            optimizer.step()
            stats = {"pg": pg_loss.item(), "v": v_loss.item(), "entropy": entropy.item()}
    return stats


class NetworkPolicy:
    """The trained network behind the package's `Policy` protocol (for the trial runner)."""

    def __init__(self, agent: Agent, greedy: bool) -> None:
        self.agent, self.greedy = agent, greedy
        self.rng = np.random.default_rng(0)

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        self.rng = rng

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        with torch.no_grad():
            dist = self.agent.dist(
                torch.as_tensor(np.array(observation, np.float32)[None]),
                torch.as_tensor(action_mask[None] > 0),
            )
        p = dist.probs[0].numpy().astype(float)
        return int(np.argmax(p)) if self.greedy else int(self.rng.choice(p.size, p=p / p.sum()))

    def update(self, *args: Any) -> None:
        return None


def value_per_hour(result: TrialResult) -> float:
    """The metric: the sum of w_i over deliveries (w as at delivery) per simulated hour."""
    return float(sum(result.delivery_value) / (result.end_s / 3600.0))


def evaluate(agent: Agent, settings: Settings) -> list[tuple[str, list[float], float]]:
    """(name, metric per evaluation seed, circuit switches per robot per hour) of every row."""
    rows: list[tuple[str, Any]] = [
        ("random", lambda a: RandomAllocator()),
        ("stay", lambda a: StayAllocator()),
    ]
    if missing_model(settings.preset) is None:
        rows.append(("static (model optimum)", StaticAllocator(model=load_model(settings.preset))))
    rows.append(("ippo greedy", lambda a: NetworkPolicy(agent, greedy=True)))
    rows.append(("ippo sampled", lambda a: NetworkPolicy(agent, greedy=False)))
    options = tavc_env.EnvOptions(observation_mode=settings.observation_mode)
    out = []
    for name, policies in rows:
        results = [
            run_trial(
                policies,
                seed=s,
                convergence_s=0.0,
                measured_s=settings.eval_hours * 3600.0,
                arena=settings.preset,
                options=options,
            )
            for s in settings.eval_seeds
        ]
        switches = np.mean([len(r.changes) / len(r.agents) / (r.end_s / 3600) for r in results])
        out.append((name, [value_per_hour(r) for r in results], float(switches)))
    return out


def table(rows: list[tuple[str, list[float], float]], settings: Settings) -> str:
    """The final table, Markdown: mean +- standard error over the evaluation seeds, and the
    mean normalised as (value - random) / (reference - random)."""
    means = {name: float(np.mean(v)) for name, v, _ in rows}
    reference = "static (model optimum)" if "static (model optimum)" in means else "stay"
    span = means[reference] - means["random"]
    lines = [
        f"Delivered value per simulated hour on {settings.preset}, {len(settings.eval_seeds)} "
        f"seeds x {settings.eval_hours:g} h (seeds {list(settings.eval_seeds)})",
        "",
        f"| policy | value / h | s.e. | normalised to {reference} | switches / robot / h |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, values, switches in rows:
        se = float(np.std(values, ddof=1) / np.sqrt(len(values))) if len(values) > 1 else 0.0
        norm = (means[name] - means["random"]) / span if span else float("nan")
        lines.append(f"| {name} | {means[name]:.0f} | {se:.0f} | {norm:.3f} | {switches:.2f} |")
    return "\n".join(lines)


def policy_table(agent: Agent, settings: Settings) -> str:
    """What the network does with the paper's state (and the robot's index, in `paper_id`): the
    probability of choosing each circuit, by robot and last circuit. Empty for `rich`, whose
    observations cannot be listed."""
    if settings.observation_mode == "rich":
        return ""
    config = tavc_env.preset(settings.preset)
    n, m = config.n_robots, config.n_circuits
    lines = ["P(next circuit) by robot and last circuit:", ""]
    lines += ["| robot | speed | last | " + " | ".join(f"P({c})" for c in range(m)) + " |"]
    lines += ["|---|---:|---:|" + "---:|" * m]
    for i in range(n if settings.observation_mode == "paper_id" else 1):
        for last in range(m):
            x = np.eye(m, dtype=np.float32)[last]
            if settings.observation_mode == "paper_id":
                x = np.concatenate([x, np.eye(n, dtype=np.float32)[i]])
            with torch.no_grad():
                p = agent.dist(torch.as_tensor(x[None]), torch.ones(1, m, dtype=torch.bool)).probs[
                    0
                ]
            robot = f"robot_{i}" if settings.observation_mode == "paper_id" else "any"
            speed = (
                f"{config.robots[i].speed:g}" if settings.observation_mode == "paper_id" else "-"
            )
            cells = " | ".join(f"{float(q):.2f}" for q in p)
            lines.append(f"| {robot} | {speed} | {last} | {cells} |")
    return "\n".join(lines)


def train(settings: Settings) -> tuple[Agent, str]:
    """Train, evaluate; the network and the final table."""
    torch.manual_seed(settings.seed)
    torch.set_num_threads(1)  # deterministic, and one core per run
    rng = np.random.default_rng(settings.seed)
    env = tavc_env.parallel_env(
        preset=settings.preset,
        reward="value",
        observation_mode=settings.observation_mode,
        max_sim_time_s=settings.rollout_hours * 3600.0,
        max_cycles=10**9,
    )
    robot = env.possible_agents[0]
    n_obs = env.observation_space(robot)["observation"].shape[0]
    agent = Agent(n_obs, env.config.n_circuits, settings.hidden)
    optimizer = torch.optim.Adam(agent.parameters(), lr=settings.learning_rate, eps=1e-5)
    gamma_s = settings.gamma_per_hour ** (1.0 / 3600.0)
    scale = max(c.value for c in env.config.circuits)  # rewards of about 1 per delivery
    updates = max(1, round(settings.total_hours / settings.rollout_hours))
    started = time.perf_counter()
    for k in range(updates):
        trajectories, train_metric = rollout(env, agent, int(rng.integers(2**31)), settings, scale)
        batch = advantages(trajectories, gamma_s, settings.gae_lambda)
        stats = update(agent, optimizer, batch, settings, rng)
        print(
            f"update {k + 1}/{updates}  hours {(k + 1) * settings.rollout_hours:g}  "
            f"decisions {len(batch)}  train value/h {train_metric:.0f}  "
            f"entropy {stats.get('entropy', float('nan')):.3f}  v_loss {stats.get('v', float('nan')):.3f}  "
            f"wall {time.perf_counter() - started:.0f} s",
            flush=True,
        )
    result = table(evaluate(agent, settings), settings)
    summary = policy_table(agent, settings)
    result += f"\n\n{summary}" if summary else ""
    print(result, flush=True)
    if settings.out is not None:
        settings.out.parent.mkdir(parents=True, exist_ok=True)
        settings.out.write_text(result + "\n")
    return agent, result


if __name__ == "__main__":
    train(tyro.cli(Settings))
