"""The arena as an RLlib `MultiAgentEnv`, by default in the deciders-only (semi-Markov) view.

RLlib's `MultiAgentEnv` lets only the agents that act appear in a step, so by default this adapter
wraps `tavc_env.adapters.deciders.DecidersOnly`: a robot appears when it must decide, with the
reward earned since its previous decision, and every robot appears once more when the episode
ends. `deciders_only=False` gives the plain env (every robot every step).

Observations: with `observation_format="dict"` (default) the Dict is renamed to the keys RLlib's
action-masking module expects, `observations` and `action_mask`
(`ray.rllib.examples.rl_modules.classes.action_masking_rlm.ActionMaskingTorchRLModule`); with
`"box"` the vector alone, which RLlib's default PPO encoder takes. Needs `ray[rllib]` (the `marl`
extra).

    from ray.tune.registry import register_env
    register_env("tavc", lambda config: RllibArenaEnv(config))
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from ray.rllib.env.multi_agent_env import MultiAgentEnv

from tavc_env.adapters import checked_reward_scale
from tavc_env.adapters.deciders import DecidersOnly
from tavc_env.arena import make_env
from tavc_env.validation import require

RLLIB_OBS_KEY = "observations"  # the key RLlib's action-masking module reads


class RllibArenaEnv(MultiAgentEnv):
    """The arena for RLlib. Its config (one mapping, as RLlib passes it) holds:

    - `deciders_only`: True (default) for the semi-Markov view, False for every robot every step;
    - `reward_scale`: rewards are multiplied by it (the env's `w / t`, t in ms, is about 0.03);
    - every other key: an env argument (`tavc_env.arena.make_env`): a `scenario`, or a `preset`
      or `config` with arena overrides, and env options.
    """

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        super().__init__()
        kwargs = dict(config or {})
        deciders_only = kwargs.pop("deciders_only", True)
        require(isinstance(deciders_only, bool), "deciders_only", deciders_only, "True or False")
        self.reward_scale = checked_reward_scale(kwargs.pop("reward_scale", 1.0))
        arena = make_env(**kwargs)
        self.arena = arena
        self.view: Any = DecidersOnly(arena) if deciders_only else arena
        self.possible_agents = list(arena.possible_agents)
        self.agents = list(self.possible_agents)
        inner: Any = arena.observation_space(self.possible_agents[0])
        self._dict = isinstance(inner, spaces.Dict)
        space = (
            spaces.Dict({RLLIB_OBS_KEY: inner["observation"], "action_mask": inner["action_mask"]})
            if self._dict
            else inner
        )
        self.observation_spaces = dict.fromkeys(self.possible_agents, space)
        self.action_spaces = {a: arena.action_space(a) for a in self.possible_agents}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        obs, infos = self.view.reset(seed=seed, options=options)
        self.agents = list(self.possible_agents)
        return self._rename(obs), infos

    def step(self, action_dict: dict[str, Any]) -> tuple[Any, ...]:
        obs, rewards, terms, truncs, infos = self.view.step(
            {a: int(np.asarray(x)) for a, x in action_dict.items()}
        )
        ended = not self.arena.agents
        if ended:
            self.agents = []
        terminateds = {**terms, "__all__": ended and any(terms.values())}
        truncateds = {**truncs, "__all__": ended and not any(terms.values())}
        scaled = {a: r * self.reward_scale for a, r in rewards.items()}
        return self._rename(obs), scaled, terminateds, truncateds, infos

    def _rename(self, obs: Mapping[str, Any]) -> dict[str, Any]:
        if not self._dict:
            return dict(obs)
        return {
            a: {RLLIB_OBS_KEY: o["observation"], "action_mask": o["action_mask"]}
            for a, o in obs.items()
        }
