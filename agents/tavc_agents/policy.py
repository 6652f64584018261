"""The `Policy` protocol: what any agent, ours or a researcher's, implements to drive one robot.

A policy sees only what its robot gets from the environment: its observation (one-hot of the last
circuit), the action mask, its reward and its info dict. It never sees speeds, positions of others
or the simulator.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from tavc_env.config import ArenaConfig


@runtime_checkable
class Policy(Protocol):
    """One robot's decision maker.

    The trial runner calls `reset` once per trial, `act` at each of the robot's decision epochs, and
    `update` when the task chosen at the previous epoch has completed (with the reward the env paid
    for it), just before the next `act`.
    """

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        """Start afresh; `rng` is this policy's own random stream."""

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        """The circuit to serve next, among those allowed by `action_mask`."""

    def update(
        self,
        observation: np.ndarray,
        action: int,
        reward: float,
        next_observation: np.ndarray,
        info: dict[str, Any],
    ) -> None:
        """Learn from a completed task: in `observation` it chose `action`, was paid `reward`, and
        now observes `next_observation` (`info` carries e.g. `task_time_s`)."""


class NonLearning:
    """Base for allocators that do not learn: `update` does nothing."""

    def update(
        self,
        observation: np.ndarray,
        action: int,
        reward: float,
        next_observation: np.ndarray,
        info: dict[str, Any],
    ) -> None:
        return None


def generator(rng: np.random.Generator | None, owner: object) -> np.random.Generator:
    """`rng`, the random stream `owner` was given by `reset`; a ValueError if it was never reset
    (a policy used before `reset` must not silently run on some default seed)."""
    if rng is None:
        raise ValueError(
            f"{type(owner).__name__} was used before reset(rng, n_actions); allowed: call reset "
            "with the policy's random generator first"
        )
    return rng


def allowed_actions(action_mask: np.ndarray) -> np.ndarray:
    """Indices the mask allows; a ValueError if it allows none."""
    allowed = np.flatnonzero(np.asarray(action_mask) > 0)
    if allowed.size == 0:
        raise ValueError(f"action_mask = {action_mask!r} allows no action; allowed: at least one 1")
    return allowed


def state_of(observation: np.ndarray) -> int:
    """The tabular state of the paper's observation: the index of the last circuit."""
    return int(np.argmax(observation))


@runtime_checkable
class Team(Protocol):
    """A centralised (or communicating) allocator: it makes every robot's policy for a trial and,
    through `observe`, sees what the environment publicly reports about every robot.

    This is the documented channel through which coordination-based baselines get their
    information: the info dicts of all robots after each step (circuit, phase, broken, task times)
    and the circuits' current values, never the simulator's internals. The trial runner calls
    `policies` once per trial, then `observe` after `reset`, after each step and after each
    scheduled event, always before any robot acts.
    """

    def policies(self, agents: list[str], config: ArenaConfig) -> dict[str, Policy]:
        """One policy per agent for a trial in the arena `config`."""

    def observe(
        self, infos: Mapping[str, Mapping[str, Any]], circuit_values: Sequence[float]
    ) -> None:
        """What every robot's info says now, and the value of each circuit now."""
