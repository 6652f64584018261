"""Baseline allocators behind the `Policy` protocol."""

from __future__ import annotations

import numpy as np

from tavc_agents.policy import NonLearning, allowed_actions, generator, state_of


class RandomAllocator(NonLearning):
    """Uniformly random choice among the allowed circuits: the paper's comparison condition."""

    def __init__(self) -> None:
        self._rng: np.random.Generator | None = None

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        self._rng = rng

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        allowed = allowed_actions(action_mask)
        return int(allowed[generator(self._rng, self).integers(allowed.size)])


class FixedAllocator(NonLearning):
    """Always the same circuit (a pre-programmed robot; used for interference and model checks)."""

    def __init__(self, circuit: int) -> None:
        if not isinstance(circuit, int) or circuit < 0:
            raise ValueError(f"circuit = {circuit!r} is invalid; allowed: a circuit index >= 0")
        self.circuit = circuit

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        if self.circuit >= n_actions:
            raise ValueError(
                f"circuit = {self.circuit} is invalid; allowed: a circuit index in [0, {n_actions - 1}]"
            )

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        if not action_mask[self.circuit]:
            raise ValueError(
                f"circuit {self.circuit} is masked out (mask {action_mask.tolist()}); a fixed "
                "allocator can only be asked when every circuit is allowed"
            )
        return self.circuit


class StayAllocator(NonLearning):
    """Keep serving the circuit last served (the paper's observation): the start's allocation,
    held. Where the reset already spreads the robots well, a strong and trivial baseline."""

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        return None

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        last = state_of(observation)
        if not action_mask[last]:
            raise ValueError(
                f"the last circuit {last} is masked out (mask {action_mask.tolist()}); allowed: a "
                "mask that allows the robot's last circuit"
            )
        return last
