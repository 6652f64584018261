"""Many model-twin trials at once: the twin's decision process (`tavc_env.twin`) with TAVC or
random robots, vectorised over trials with numpy, for power analyses that need thousands of trials.

    tables = InterferenceTables.from_dict(...)        # e.g. the regime map's twin_tables/
    out = run_batch(tavc_env.make_config("dahl2004"), tables, Learner("softmax", 0.005),
                    trials=2000, rng=np.random.default_rng(0))
    out.fast_share - out.slow_share                   # one value per trial

A second implementation of what `run_trial(..., env_factory=twin_parallel_env)` does with the
allocators `softmax_tavc`, `epsilon_tavc` (`tavc_agents.learners.tavc`) and `random`, written for
throughput: one numpy step takes every unfinished trial to its next task completion. The same
process, step for step:

* at the start the robots stand on the circuits in an order drawn per trial (rank mod circuits) and
  all choose; once all have chosen, each draws its task time from its cell of the tables (the
  robots of each class committed to its circuit, itself included), times the switch cost if it
  changed circuits;
* at a completion the robot earns `w / t` (t in ms, the env's default), updates
  Q(s, a) += alpha (r + gamma max Q(a, .) - Q(s, a)) (with the scaled initialisation, the first
  reward first sets every entry to r / (1 - gamma) (1 + optimism) with relative noise), chooses
  its next circuit from the row of its new state, and draws the next task time;
* measures over the measured window as `tavc_agents.analysis.measures`: each robot's share of time on
  the high-value circuit (its current task's circuit), delivered value per robot per 10 s, time in
  each fast:slow state, and the final Q gap Q(s, high) - max Q(s, other) averaged over states.

Not covered (a ValueError says so): breakdowns, priority changes, other allocators. The random
streams differ from the Policy-based twin's, so the two agree in distribution, not trial by trial;
`benchmarks/twin_batch.py` checks that agreement against the regime map's twin trials.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from tavc_agents.learners.tavc import TavcParams
from tavc_env.config import ArenaConfig
from tavc_env.twin import InterferenceTables, team_classes
from tavc_env.validation import is_integer, is_number, require

REWARD_UNIT = 1000.0  # the env's default reward time unit: t in ms


@dataclass(frozen=True)
class Learner:
    """The robots' allocator: softmax TAVC (`parameter`: the temperature), epsilon-greedy TAVC
    (`parameter`: epsilon) or random choice (no parameter), with TAVC's learning parameters."""

    kind: Literal["softmax", "epsilon", "random"]
    parameter: float = 0.0
    params: TavcParams = field(default_factory=TavcParams)

    def __post_init__(self) -> None:
        require(
            self.kind in ("softmax", "epsilon", "random"),
            "learner.kind",
            self.kind,
            "'softmax', 'epsilon' or 'random'",
        )
        if self.kind == "softmax":
            ok = is_number(self.parameter) and self.parameter > 0
            require(ok, "learner.parameter", self.parameter, "a softmax temperature > 0")
        if self.kind == "epsilon":
            ok = is_number(self.parameter) and 0 <= self.parameter <= 1
            require(ok, "learner.parameter", self.parameter, "an epsilon in [0, 1]")


@dataclass(frozen=True)
class BatchOutcome:
    """Per trial (arrays of length `trials`) the measures of the measured window; `states` is
    (trials, fast + 1, slow + 1): the fraction of the window with f fast and s slow robots on the
    high-value circuit. Q gaps are nan for random choice."""

    fast_share: np.ndarray
    slow_share: np.ndarray
    performance: np.ndarray
    q_gap_fast: np.ndarray
    q_gap_slow: np.ndarray
    states: np.ndarray
    completions: int


def run_batch(
    config: ArenaConfig,
    tables: InterferenceTables,
    learner: Learner,
    trials: int,
    rng: np.random.Generator,
    convergence_s: float = 15 * 3600.0,
    measured_s: float = 5 * 3600.0,
) -> BatchOutcome:
    """`trials` independent twin trials of `config` with `tables`, every robot a `learner`, each
    running `convergence_s` then `measured_s` simulated seconds; every draw from `rng`."""
    require(isinstance(config, ArenaConfig), "config", type(config).__name__, "an ArenaConfig")
    require(not config.breakdowns, "config.breakdowns", config.breakdowns, "none (not modelled)")
    tables.check_team(config)
    require(is_integer(trials) and trials >= 1, "trials", trials, "an integer >= 1")
    require(isinstance(rng, np.random.Generator), "rng", rng, "a numpy.random.Generator")
    for name, value in (("convergence_s", convergence_s), ("measured_s", measured_s)):
        require(is_number(value) and value > 0, name, value, "a number of seconds > 0")
    return _Batch(config, tables, learner, int(trials), rng).run(
        float(convergence_s), float(convergence_s + measured_s)
    )


class _Batch:
    def __init__(
        self,
        config: ArenaConfig,
        tables: InterferenceTables,
        learner: Learner,
        trials: int,
        rng: np.random.Generator,
    ) -> None:
        classes, team = team_classes(config)
        self.k, self.n, self.m = trials, config.n_robots, config.n_circuits
        self.rng = rng
        self.learner = learner
        self.values = np.array([c.value for c in config.circuits], dtype=float)
        self.high = int(np.argmax(self.values))
        self.robot_class = np.array([classes.index(r.speed_class) for r in config.robots])
        self.fast = np.array([r.speed_class == "fast" for r in config.robots])
        self.slow = np.array([r.speed_class == "slow" for r in config.robots])
        # the lognormal of every cell, indexed [circuit, count vector (mixed radix), class]
        self.radix = np.cumprod([1, *(t + 1 for t in team[:-1])])
        size = int(np.prod([t + 1 for t in team]))
        self.mu = np.zeros((self.m, size, len(classes)))
        self.sigma = np.zeros_like(self.mu)
        for cell in tables.cells:
            sigma = math.sqrt(math.log1p((cell.sd_s / cell.mean_s) ** 2))
            at = (
                cell.circuit,
                int(np.dot(cell.counts, self.radix)),
                classes.index(cell.robot_class),
            )
            self.mu[at] = math.log(cell.mean_s) - sigma * sigma / 2
            self.sigma[at] = sigma
        self.switch_cost = tables.switch_cost
        self.class_count = np.zeros((self.k, self.m, len(classes)), dtype=np.int64)

    # -- the learners ------------------------------------------------------------------------
    def choose(self, q_rows: np.ndarray) -> np.ndarray:
        """One circuit per row of Q-values (rows, circuits), by the learner's selection rule."""
        rows = q_rows.shape[0]
        kind, m = self.learner.kind, self.m
        if kind == "random":
            p = np.full((rows, m), 1.0 / m)
        elif kind == "softmax":
            z = np.exp((q_rows - q_rows.max(axis=1, keepdims=True)) / self.learner.parameter)
            p = z / z.sum(axis=1, keepdims=True)
        else:
            best = q_rows == q_rows.max(axis=1, keepdims=True)
            n_best = best.sum(axis=1, keepdims=True)
            eps = self.learner.parameter
            p = np.where(best, (1.0 - eps) / n_best, eps / np.maximum(m - n_best, 1))
            p = np.where(n_best == m, 1.0 / m, p)
        cdf: np.ndarray = np.cumsum(p, axis=1)
        u = self.rng.random((rows, 1)) * cdf[:, -1:]
        return np.minimum((cdf <= u).sum(axis=1), m - 1)

    def draw(self, trials: np.ndarray, robots: np.ndarray, switched: np.ndarray) -> np.ndarray:
        """Task times of `robots` in `trials` on their current circuits, crowds as they are now."""
        circuit = self.current[trials, robots]
        counts = self.class_count[trials, circuit] @ self.radix
        cls = self.robot_class[robots]
        mu, sigma = self.mu[circuit, counts, cls], self.sigma[circuit, counts, cls]
        t = np.exp(mu + sigma * self.rng.standard_normal(len(trials)))
        return np.where(switched, t * self.switch_cost, t)

    # -- the process -------------------------------------------------------------------------
    def run(self, t0: float, t1: float) -> BatchOutcome:
        k, n, m = self.k, self.n, self.m
        p = self.learner.params
        learning = self.learner.kind != "random"
        rng = self.rng
        start = np.array([rng.permutation(n) for _ in range(k)])
        self.current = np.empty((k, n), dtype=np.int64)
        np.put_along_axis(self.current, start, np.arange(n)[None, :] % m, axis=1)
        state = self.current.copy()  # each robot's observation: the circuit of its last task
        if p.init == "paper":
            q = rng.uniform(-p.init_range, p.init_range, size=(k, n, m, m))
        else:
            q = np.zeros((k, n, m, m))
        pending = np.full((k, n), p.init == "scaled")
        rows = np.repeat(np.arange(k), n)
        robots = np.tile(np.arange(n), k)
        chosen = self.choose(q[rows, robots, state.ravel()]).reshape(k, n)
        switched = chosen != state
        self.current = chosen
        np.add.at(self.class_count, (rows, chosen.ravel(), self.robot_class[robots]), 1)
        started = np.zeros((k, n))
        due = self.draw(rows, robots, switched.ravel()).reshape(k, n)

        on_high_time = np.zeros((k, n))
        state_time = np.zeros((k, int(self.fast.sum()) + 1, int(self.slow.sum()) + 1))
        delivered = np.zeros(k)
        last_event = np.zeros(k)
        active = np.arange(k)
        completions = 0
        w_max = self.values.max()
        while active.size:
            robot = due[active].argmin(axis=1)
            now = due[active, robot]
            # time on the high-value circuit over the measured window, up to this event
            overlap = np.clip(np.minimum(now, t1) - np.maximum(last_event[active], t0), 0.0, None)
            on_high = self.current[active] == self.high
            on_high_time[active] += overlap[:, None] * on_high
            f, s = on_high[:, self.fast].sum(axis=1), on_high[:, self.slow].sum(axis=1)
            state_time[active, f, s] += overlap
            last_event[active] = now
            going = now < t1
            active, robot, now = active[going], robot[going], now[going]
            if not active.size:
                break
            completions += active.size
            circuit = self.current[active, robot]
            reward = self.values[circuit] / ((now - started[active, robot]) * REWARD_UNIT)
            delivered[active] += np.where(now >= t0, self.values[circuit] / w_max, 0.0)
            if learning:
                first = pending[active, robot]
                if first.any():
                    a, r = active[first], robot[first]
                    level = reward[first] / (1.0 - p.gamma) * (1.0 + p.optimism)
                    jitter = rng.uniform(-p.noise, p.noise, size=(a.size, m, m))
                    q[a, r] = level[:, None, None] * (1.0 + jitter)
                    pending[a, r] = False
                s = state[active, robot]
                target = reward + p.gamma * q[active, robot, circuit].max(axis=1)
                q[active, robot, s, circuit] += p.alpha * (target - q[active, robot, s, circuit])
            state[active, robot] = circuit
            nxt = self.choose(q[active, robot, circuit])
            cls = self.robot_class[robot]
            np.add.at(self.class_count, (active, circuit, cls), -1)
            np.add.at(self.class_count, (active, nxt, cls), 1)
            self.current[active, robot] = nxt
            started[active, robot] = now
            due[active, robot] = now + self.draw(active, robot, nxt != circuit)
        window = t1 - t0
        share = on_high_time / window
        others = [c for c in range(m) if c != self.high]
        gap = (q[..., self.high] - q[..., others].max(axis=-1)).mean(axis=-1)  # (trials, robots)
        nan = np.full(k, math.nan)
        return BatchOutcome(
            fast_share=share[:, self.fast].mean(axis=1),
            slow_share=share[:, self.slow].mean(axis=1),
            performance=delivered / n / (window / 10.0),
            q_gap_fast=gap[:, self.fast].mean(axis=1) if learning else nan,
            q_gap_slow=gap[:, self.slow].mean(axis=1) if learning else nan,
            states=state_time / window,
            completions=completions,
        )
