"""An example plugin of tavc-env: two allocators that `tavc trial --allocator NAME`, `run_trial`
callers, sweeps and studies find by name once this package is installed (its pyproject.toml names
them in the `tavc.allocators` entry-point group)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tavc_agents.allocators.baselines import FixedAllocator
from tavc_agents.experiments.registry import team_allocator
from tavc_agents.policy import NonLearning, Policy, allowed_actions
from tavc_env import ArenaConfig


class BestRewardSoFar(NonLearning):
    """Per robot: the allowed circuit with the best reward seen so far (ties: lowest index), after
    `explore` rounds of trying each circuit in turn."""

    def __init__(self, explore: int = 1) -> None:
        if not isinstance(explore, int) or explore < 0:
            raise ValueError(f"explore = {explore!r} is invalid; allowed: an integer >= 0")
        self.explore = explore

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        self.best = np.zeros(n_actions)
        self.tried = 0

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        allowed = allowed_actions(action_mask)
        if self.tried < self.explore * len(self.best):
            self.tried += 1
            return int(allowed[self.tried % allowed.size])
        return int(allowed[np.argmax(self.best[allowed])])

    def update(
        self,
        observation: np.ndarray,
        action: int,
        reward: float,
        next_observation: np.ndarray,
        info: dict[str, Any],
    ) -> None:
        self.best[action] = max(self.best[action], reward)


class SplitTeam:
    """A team: robot k always serves circuit (k + offset) mod n, a fixed even split."""

    def __init__(self, offset: int = 0) -> None:
        self.offset = offset

    def policies(self, agents: list[str], config: ArenaConfig) -> dict[str, Policy]:
        n = len(config.circuits)
        return {a: FixedAllocator((k + self.offset) % n) for k, a in enumerate(agents)}

    def observe(
        self, infos: Mapping[str, Mapping[str, Any]], circuit_values: Sequence[float]
    ) -> None:
        return None


split_team = team_allocator(SplitTeam)
