"""The deciders-only (semi-Markov) view of the arena: only the robots that must decide appear.

In the plain env every robot is in every step, although in event-driven stepping about one in six
has to decide (with `decision_interval_s=1`, about one in a hundred): a library that stores every
transition stores mostly robots whose action is ignored. Here a step takes actions from the robots
that must decide and runs the plain env until some robot must decide again (or the episode ends).
It returns only those robots, each with

- the reward it earned since its previous decision (summed over the plain steps in between),
- `info["elapsed_s"]`: the simulated time since its previous decision (the sojourn time an
  SMDP learner discounts by, e.g. `gamma ** elapsed_s`), and every other info of the plain env.

When the episode ends, every robot is returned once more, truncated, with what it earned since its
last decision. The rewards handed out add up to the plain env's on the same trajectory.

It is PettingZoo-style (the parallel API's methods and return values), but not a PettingZoo
`ParallelEnv`: robots leave and re-enter the returned dicts, which PettingZoo's checkers do not
allow. `tavc_env.adapters.rllib` offers it as an RLlib `MultiAgentEnv`, whose API allows it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from tavc_env.env import ArenaEnv

Step = tuple[
    dict[str, Any], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict[str, Any]]
]


class DecidersOnly:
    """Wraps a `TavcArenaEnv` (or the twin: any `ArenaEnv`) so that only robots that must decide
    appear."""

    def __init__(self, env: ArenaEnv[Any]) -> None:
        if not isinstance(env, ArenaEnv):
            raise ValueError(
                f"env = {env!r} is invalid; allowed: a tavc_env arena env "
                "(tavc_env.parallel_env(...) or tavc_env.twin_parallel_env(...))"
            )
        self.env = env
        self.possible_agents = list(env.possible_agents)
        self.metadata = {**env.metadata, "name": f"{env.metadata['name']}_deciders"}
        self.agents: list[str] = []  # the robots that must decide now
        self._earned = dict.fromkeys(self.possible_agents, 0.0)

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        return self.env.observation_space(agent)

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self.env.action_space(agent)

    @property
    def unwrapped(self) -> ArenaEnv[Any]:
        return self.env

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        obs, infos = self.env.reset(seed=seed, options=options)
        self._earned = dict.fromkeys(self.possible_agents, 0.0)
        deciders = [a for a in self.env.agents if infos[a]["action_required"]]
        if not deciders:  # (a start with nobody deciding: no shipped arena has one)
            obs, _, _, infos, deciders = self._until_someone_decides({})
        self.agents = deciders
        return {a: obs[a] for a in deciders}, {a: infos[a] for a in deciders}

    def step(self, actions: dict[str, Any]) -> Step:
        """Actions of the robots in `agents` (others are refused: they have nothing to decide)."""
        if not self.env.agents:
            raise ValueError("step() called on a finished episode; call reset() first")
        extra = sorted(set(actions) - set(self.agents))
        if extra:
            raise ValueError(
                f"actions for {extra} are invalid: those robots need not decide now; "
                f"allowed: actions for the robots that must decide, {self.agents}"
            )
        obs, terms, truncs, infos, deciders = self._until_someone_decides(actions)
        ended = not self.env.agents
        shown = list(infos) if ended else deciders
        self.agents = [] if ended else deciders
        paid = {a: self._earned[a] for a in shown}
        for a in shown:
            self._earned[a] = 0.0
        return (
            {a: obs[a] for a in shown},
            paid,
            {a: terms[a] for a in shown},
            {a: truncs[a] for a in shown},
            {a: infos[a] for a in shown},
        )

    def _until_someone_decides(
        self, actions: dict[str, Any]
    ) -> tuple[dict[str, Any], dict[str, bool], dict[str, bool], dict[str, Any], list[str]]:
        """Step the plain env with `actions`, then with none, until some robot must decide or the
        episode ends; every reward paid on the way is added to its robot's earnings. Returns the
        last step's observations, terminations, truncations and infos, and who must decide."""
        while True:
            obs, rewards, terms, truncs, infos = self.env.step(actions)
            actions = {}
            for a, r in rewards.items():
                self._earned[a] += r
            deciders = [a for a in infos if infos[a]["action_required"]]
            if deciders or not self.env.agents:
                return obs, terms, truncs, infos, deciders

    def state(self) -> np.ndarray:
        return self.env.state()

    def render(self) -> np.ndarray | None:
        return self.env.render()

    def close(self) -> None:
        self.env.close()
