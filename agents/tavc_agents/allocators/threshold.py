"""A response-threshold allocator: robots answer the stimulus of under-served circuits.

Follows the fixed response threshold model of Bonabeau, Theraulaz & Deneubourg (Proc. R. Soc. B
1996) with threshold reinforcement (Theraulaz, Bonabeau & Deneubourg, Proc. R. Soc. B 1998), as used
for robot teams by Krieger & Billeter (2000) and Agassounon & Martinoli (2002): an individual with
threshold theta engages a task of stimulus s with tendency s^2 / (s^2 + theta^2); performing a task
lowers one's threshold for it (learning), not performing it raises it (forgetting), so individuals
specialise.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tavc_agents.allocators.teams import TeamAllocator
from tavc_agents.learners.selection import sample
from tavc_agents.policy import generator
from tavc_env.env import completed_task_s
from tavc_env.validation import is_number, require


class ResponseThresholdAllocator(TeamAllocator):
    """Response-threshold allocation with threshold reinforcement.

    Stimulus of circuit i: how long it has been going without deliveries, weighted by its value,
    `s_i = (w_i / max w) * max(g_i, now - last_i)`, where `last_i` is the time of the latest
    delivery on circuit i and `g_i` the running mean (weight `memory`) of the gaps between its
    deliveries: a circuit served by fewer or slower robots calls louder. Robot r deciding picks
    circuit i with probability proportional to `s_i^2 / (s_i^2 + theta_{r,i}^2)` (uniformly if all
    stimuli are zero). After a task of t seconds on circuit a, `theta_{r,a} -= xi * t` and every
    other `theta_{r,i} += phi * t`, kept in `[theta_min, theta_max]`.

    Knows: the deliveries announced by every robot (circuit and time, as a sink-side counter would
    broadcast) and the circuits' current values. Not speeds, not the model.

    Defaults: stimuli in `dahl2004` are 20-40 s (about three robots per circuit), so thresholds
    start at 30 s, in the middle; a 70 s task moves the thresholds by 7 s and 3.5 s, so a robot
    that keeps a circuit for a few tasks specialises (with theta 1 s against 100 s it switches on
    about 8 % of decisions, like epsilon-greedy), while a starving circuit's stimulus still grows
    until someone answers it.
    """

    def __init__(
        self,
        theta0: float = 30.0,
        xi: float = 0.1,
        phi: float = 0.05,
        theta_min: float = 1.0,
        theta_max: float = 100.0,
        memory: float = 0.1,
    ) -> None:
        super().__init__()
        require(
            is_number(theta_min) and is_number(theta_max) and 0 < theta_min <= theta_max,
            "theta bounds",
            (theta_min, theta_max),
            "0 < theta_min <= theta_max",
        )
        require(
            is_number(theta0) and theta_min <= theta0 <= theta_max,
            "theta0",
            theta0,
            f"a threshold in [theta_min, theta_max] = [{theta_min}, {theta_max}] s",
        )
        for name, value in (("xi", xi), ("phi", phi)):
            require(is_number(value) and value >= 0, name, value, "a rate >= 0 per second")
        require(is_number(memory) and 0 < memory <= 1, "memory", memory, "a weight in (0, 1]")
        self.theta0, self.xi, self.phi = float(theta0), float(xi), float(phi)
        self.theta_min, self.theta_max = float(theta_min), float(theta_max)
        self.memory = float(memory)
        self.theta = np.zeros((0, 0))
        self.last = np.zeros(0)
        self.gap = np.zeros(0)

    def setup(self) -> None:
        self.theta = np.full((len(self.agents), self.n_actions), self.theta0)
        self.last = np.zeros(self.n_actions)
        self.gap = np.full(self.n_actions, np.nan)

    def on_observe(self, infos: Mapping[str, Mapping[str, Any]]) -> None:
        for info in infos.values():
            if completed_task_s(info) is None:
                continue
            i, now = int(info["circuit"]), float(info["sim_time_s"])
            gap = now - self.last[i]
            self.gap[i] = (
                gap if np.isnan(self.gap[i]) else self.gap[i] + self.memory * (gap - self.gap[i])
            )
            self.last[i] = now

    def stimuli(self) -> np.ndarray:
        """Each circuit's stimulus now (value-weighted seconds without service)."""
        waiting = self.now - self.last
        gaps = np.where(np.isnan(self.gap), waiting, np.maximum(self.gap, waiting))
        return np.asarray(self.values) / max(self.values) * gaps

    def tendencies(self, robot: int) -> np.ndarray:
        """s^2 / (s^2 + theta^2) for robot `robot` and each circuit."""
        s2 = self.stimuli() ** 2
        return s2 / (s2 + self.theta[robot] ** 2)

    def choose(self, robot: int, allowed: np.ndarray) -> int:
        weights = np.zeros(self.n_actions)
        weights[allowed] = self.tendencies(robot)[allowed]
        if weights.sum() <= 0:
            weights[allowed] = 1.0
        return sample(weights / weights.sum(), generator(self.rngs[robot], self))

    def learn(
        self, robot: int, previous: int, action: int, reward: float, info: Mapping[str, Any]
    ) -> None:
        t = completed_task_s(info)
        if t is None:
            return
        row = self.theta[robot]
        row += self.phi * t
        row[action] -= (self.xi + self.phi) * t
        np.clip(row, self.theta_min, self.theta_max, out=row)
