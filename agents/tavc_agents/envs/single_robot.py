"""One robot of the arena as a Gymnasium env, for single-agent RL libraries.

The learner controls one robot; every other robot is driven by its own `Policy` (softmax TAVC by
default), exactly as in a trial. One `step` is one of the learner's tasks: from its decision to its
next decision epoch, however many environment steps that takes; the reward is what the arena paid
the learner for it (`w_i / t`, Equation 2). The observation is the paper's: the one-hot of the
learner's last circuit. An episode ends (truncated) after `episode_s` simulated seconds.

Vectorised (`gymnasium.make_vec("tavc/dahl2004-v0", n, vectorization_mode="async")`, ids in
`tavc_env.registration`), each copy is built in its worker from the id's arguments; the env
also pickles at any point (the arena replays its episode, DESIGN.md section 2.3).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from tavc_agents.driver import PolicyDriver
from tavc_agents.learners.tavc import softmax_tavc
from tavc_agents.policy import Policy
from tavc_env.arena import resolve_env_kwargs
from tavc_env.validation import is_integer, is_number, require


def softmax_tavc_others(agent: str) -> Policy:
    """The default policy of the robots that do not learn: softmax TAVC (a module-level function,
    not a lambda, so that the env pickles)."""
    return softmax_tavc()


class SingleRobotEnv(gymnasium.Env[np.ndarray, int]):
    """Robot `robot` learns; the others follow `others(agent)` (default: softmax TAVC)."""

    # NEXT_STEP is what `make_vec` builds by default, so the declaration is what users get. It
    # suits a semi-MDP: the truncating step returns the episode's last observation itself (a
    # learner bootstraps from it), and the extra reset step has reward 0 and ignores its action.
    metadata: dict[str, Any] = {  # noqa: RUF012 (Gymnasium declares it an instance variable)
        "render_modes": [],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        robot: str = "robot_0",
        others: Callable[[str], Policy] | None = None,
        episode_s: float | None = None,
        scenario: str | None = None,
        **env_kwargs: Any,
    ) -> None:
        arena, options = resolve_env_kwargs({"scenario": scenario, **env_kwargs})
        if episode_s is None:
            episode_s = 4 * 3600.0 if arena.scenario is None else arena.scenario.episode_s
        require(is_number(episode_s) and episode_s > 0, "episode_s", episode_s, "a duration > 0 s")
        require(
            "max_sim_time_s" not in env_kwargs,
            "max_sim_time_s",
            env_kwargs.get("max_sim_time_s"),
            "not given (set from episode_s: an episode lasts episode_s simulated seconds)",
        )
        require(
            others is None or callable(others),
            "others",
            others,
            "None (softmax TAVC) or a function from an agent name to its Policy",
        )
        self.env = arena.parallel_env(max_sim_time_s=float(episode_s), **options)
        require(robot in self.env.possible_agents, "robot", robot, str(self.env.possible_agents))
        self.robot = robot
        self.others = others if others is not None else softmax_tavc_others
        m = self.env.config.n_circuits
        self.observation_space = spaces.Box(0.0, 1.0, (m,), np.float32)
        self.n_circuits = m
        self.action_space: spaces.Discrete = spaces.Discrete(m)  # type: ignore[assignment, type-arg, unused-ignore]
        self._driver = PolicyDriver({})
        self._obs: dict[str, Any] = {}
        self._infos: dict[str, Any] = {}
        self._rewards: dict[str, float] = {}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        require(
            seed is None or (is_integer(seed) and seed >= 0),
            "seed",
            seed,
            "None or an integer >= 0 (int or numpy integer; not bool, not float)",
        )
        require(
            options is None or isinstance(options, Mapping),
            "options",
            options,
            "None or a mapping (this env takes no reset options)",
        )
        seed = None if seed is None else int(seed)
        super().reset(seed=seed)
        # Without a seed the episode's streams come from the env's generator (seeded by the last
        # seeded reset), so a run seeded once stays reproducible: vector envs autoreset so.
        entropy = seed if seed is not None else int(self.np_random.integers(2**63))
        streams = np.random.SeedSequence(entropy).spawn(len(self.env.possible_agents) + 1)
        policies = {}
        for agent, stream in zip(self.env.possible_agents, streams[1:]):
            if agent != self.robot:
                policy = self.others(agent)
                policy.reset(np.random.default_rng(stream), self.env.config.n_circuits)
                policies[agent] = policy
        self._driver = PolicyDriver(policies)
        self._obs, self._infos = self.env.reset(seed=int(streams[0].generate_state(1)[0]))
        self._rewards = {}
        self._advance(None)  # up to the learner's first decision (at reset: at once)
        return self._obs[self.robot]["observation"].copy(), dict(self._infos[self.robot])

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        a: Any = action  # anything a caller may pass; checked below
        if isinstance(a, np.ndarray) and a.shape == ():
            a = a.item()
        require(
            is_integer(a) and 0 <= a < self.n_circuits,
            "action",
            action,
            f"a circuit index in [0, {self.n_circuits - 1}] (an int or numpy integer)",
        )
        reward, ended = self._advance(int(a))
        info = dict(self._infos[self.robot])
        return self._obs[self.robot]["observation"].copy(), reward, False, ended, info

    def _advance(self, action: int | None) -> tuple[float, bool]:
        """Step the arena until the learner must decide again (or the episode ends); return the
        learner's reward in between and whether the episode ended."""
        reward = 0.0
        first = True
        while self.env.agents:
            deciding = self._infos[self.robot]["action_required"]
            if deciding and (action is None or not first):
                return reward, False  # the learner's turn: the caller chooses
            actions = self._driver.actions(self._obs, self._rewards, self._infos)
            if deciding and action is not None:
                actions[self.robot] = action
            first = False
            self._obs, self._rewards, _, _, self._infos = self.env.step(actions)
            reward += self._rewards[self.robot]
        return reward, True
