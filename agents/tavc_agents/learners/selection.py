"""Action selection over a row of Q-values: epsilon-greedy and Boltzmann softmax.

Both return the probability of every action (so tests can check them against closed forms) and
sample from it with the caller's generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from tavc_agents.policy import allowed_actions


class Selection(Protocol):
    """Maps Q-values of one state and an action mask to action probabilities."""

    def probabilities(self, q: np.ndarray, action_mask: np.ndarray) -> np.ndarray: ...


def sample(probabilities: np.ndarray, rng: np.random.Generator) -> int:
    """One draw from a discrete distribution (inverse CDF on one uniform: one RNG call per draw)."""
    cdf = np.cumsum(probabilities)
    return int(min(np.searchsorted(cdf, rng.random() * cdf[-1], side="right"), len(cdf) - 1))


@dataclass(frozen=True)
class EpsilonGreedy:
    """The paper's Greedy-epsilon: the greedy action with probability 1 - epsilon; otherwise one of
    the other allowed actions, uniformly (for two circuits: the other one with probability epsilon,
    as in the paper). Ties for the greedy action are split evenly."""

    epsilon: float = 0.1

    def __post_init__(self) -> None:
        if not (isinstance(self.epsilon, (int, float)) and 0.0 <= self.epsilon <= 1.0):
            raise ValueError(f"epsilon = {self.epsilon!r} is invalid; allowed: a number in [0, 1]")

    def probabilities(self, q: np.ndarray, action_mask: np.ndarray) -> np.ndarray:
        allowed = allowed_actions(action_mask)
        p = np.zeros(len(q))
        values = q[allowed]
        best = allowed[values == values.max()]
        others = np.setdiff1d(allowed, best)
        if others.size == 0:
            p[best] = 1.0 / best.size
            return p
        p[best] = (1.0 - self.epsilon) / best.size
        p[others] = self.epsilon / others.size
        return p


@dataclass(frozen=True)
class Softmax:
    """Boltzmann softmax: P(a) proportional to exp(Q(a) / temperature) over allowed actions.

    Computed as exp((Q - max Q) / temperature), so it neither overflows for huge Q / temperature
    ratios nor loses the greedy action for tiny temperatures."""

    temperature: float = 0.005

    def __post_init__(self) -> None:
        ok = isinstance(self.temperature, (int, float)) and math.isfinite(self.temperature)
        if not (ok and self.temperature > 0):
            raise ValueError(
                f"temperature = {self.temperature!r} is invalid; allowed: a finite number > 0"
            )

    def probabilities(self, q: np.ndarray, action_mask: np.ndarray) -> np.ndarray:
        allowed = allowed_actions(action_mask)
        p = np.zeros(len(q))
        z = (q[allowed] - q[allowed].max()) / self.temperature
        e = np.exp(z)
        p[allowed] = e / e.sum()
        return p
