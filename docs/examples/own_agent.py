"""Bring your own agent: implement the `Policy` protocol (`reset`, `act`, `update`) and hand it to
the trial runner. This one is a UCB1 bandit on the rate of value `w / t` of each circuit, learned
from the robot's own rewards, compared with the paper's softmax TAVC robots on the same seed.

    python docs/examples/own_agent.py
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tavc_agents.experiments.runner import run_trial
from tavc_agents.learners.tavc import softmax_tavc
from tavc_agents.policy import allowed_actions
from tavc_env import metrics


class UcbRobot:
    """UCB1 over circuits: the mean reward of each circuit plus an exploration bonus."""

    def __init__(self, bonus: float = 0.002) -> None:
        self.bonus = bonus
        self.counts = np.zeros(0)
        self.means = np.zeros(0)

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        self.counts = np.zeros(n_actions)
        self.means = np.zeros(n_actions)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        allowed = allowed_actions(action_mask)
        untried = [a for a in allowed if self.counts[a] == 0]
        if untried:
            return int(untried[0])
        total = self.counts[allowed].sum()
        scores = self.means[allowed] + self.bonus * np.sqrt(
            2 * math.log(total) / self.counts[allowed]
        )
        return int(allowed[np.argmax(scores)])

    def update(
        self,
        observation: np.ndarray,
        action: int,
        reward: float,
        next_observation: np.ndarray,
        info: dict[str, Any],
    ) -> None:
        self.counts[action] += 1
        self.means[action] += (reward - self.means[action]) / self.counts[action]


def compare(hours: float = 4.0, seed: int = 0) -> dict[str, float]:
    """Delivered value per robot per 10 s in the last hour, for UCB1 and for softmax TAVC."""
    out = {}
    for name, factory in (
        ("ucb1", lambda agent: UcbRobot()),
        ("softmax_tavc", lambda a: softmax_tavc()),
    ):
        result = run_trial(factory, seed=seed, convergence_s=(hours - 1) * 3600, measured_s=3600)
        t0, t1 = result.measured_window
        out[name] = metrics.value_rate(
            result.delivery_time_s, result.delivery_circuit, result.values, 6, t0, t1
        )
    return out


if __name__ == "__main__":
    print(compare())
