"""The arena as a Stable-Baselines3 `VecEnv`: every robot of every copy is one slot, so one policy
(PPO, MaskablePPO) is shared by all robots, with the action masks where sb3-contrib looks for them.

PettingZoo's own recipe (SuperSuit's `pettingzoo_env_to_vec_env_v1` + `concat_vec_envs_v1`) fails
here: its `ConcatVecEnv` has no `seed`, `env_method` or `has_attr`, so `seed=` and MaskablePPO
crash, and it never marks time-limit ends as truncations (SB3 then does not bootstrap the value).
This adapter has all of them: `action_masks()` (and `env_method("action_masks")`), seeding
through `VecEnv.seed`, `terminal_observation` and `TimeLimit.truncated` in the infos at the end
of an episode, after which the copy is reset. Observations are the env's vector
(`observation_format="box"`); choose `observation_mode="paper_id"` or `"rich"` so that a shared
network can tell the robots apart. Needs `stable-baselines3` (the `marl` extra).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

from tavc_env.adapters import checked_reward_scale
from tavc_env.arena import make_env
from tavc_env.validation import is_integer, require


class SharedPolicyVecEnv(VecEnv):
    """`n_envs` arena envs, each robot a slot: `num_envs = n_envs * n_robots`.

    Args:
        n_envs: copies of the arena stepped in turn.
        reward_scale: rewards are multiplied by it (the env's `w / t` with t in ms is about 0.03).
        **env_kwargs: env arguments (`tavc_env.arena.make_env`: a `scenario`, or a `preset` or
            `config` with arena overrides, and env options; `observation_format` is "box").
    """

    def __init__(self, n_envs: int = 1, reward_scale: float = 1.0, **env_kwargs: Any) -> None:
        require(is_integer(n_envs) and n_envs >= 1, "n_envs", n_envs, "an integer >= 1")
        self.reward_scale = checked_reward_scale(reward_scale)
        fmt = env_kwargs.pop("observation_format", "box")
        require(fmt == "box", "observation_format", fmt, "'box' (SB3's MlpPolicy takes a vector)")
        self.envs = [make_env(observation_format="box", **env_kwargs) for _ in range(n_envs)]
        self.robots = list(self.envs[0].possible_agents)
        first = self.robots[0]
        self.render_mode = None
        super().__init__(
            n_envs * len(self.robots),
            self.envs[0].observation_space(first),
            self.envs[0].action_space(first),
        )
        self._masks = np.ones((self.num_envs, int(self.action_space.n)), dtype=np.bool_)
        self._actions = np.zeros(self.num_envs, np.int64)

    # -- VecEnv ----------------------------------------------------------------------------------
    def reset(self) -> np.ndarray:
        n = len(self.robots)
        rows = []
        for e, env in enumerate(self.envs):
            seed = self._seeds[e * n]
            obs, infos = env.reset(seed=seed)
            rows.append(self._take(e, obs, infos))
            for i, robot in enumerate(self.robots):
                self.reset_infos[e * n + i] = dict(infos[robot])
        self._reset_seeds()
        self._reset_options()
        return np.concatenate(rows)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions).reshape(self.num_envs)

    def step_wait(self) -> VecEnvStepReturn:
        n = len(self.robots)
        rows, rewards, dones, all_infos = [], [], [], []
        for e, env in enumerate(self.envs):
            chosen = self._actions[e * n : (e + 1) * n]
            # (robots that need not decide may be given any action: the env ignores it)
            obs, reward, term, trunc, infos = env.step(
                {r: int(a) for r, a in zip(self.robots, chosen)}
            )
            row = self._take(e, obs, infos)
            done = not env.agents
            slot_infos: list[dict[str, Any]] = [dict(infos[r]) for r in self.robots]
            if done:
                for i, r in enumerate(self.robots):
                    slot_infos[i]["terminal_observation"] = row[i]
                    slot_infos[i]["TimeLimit.truncated"] = bool(trunc[r] and not term[r])
                obs, infos = env.reset()
                row = self._take(e, obs, infos)
            rows.append(row)
            rewards += [reward[r] * self.reward_scale for r in self.robots]
            dones += [done] * n
            all_infos += slot_infos
        return np.concatenate(rows), np.asarray(rewards, np.float32), np.asarray(dones), all_infos

    def close(self) -> None:
        for env in self.envs:
            env.close()

    def action_masks(self) -> np.ndarray:
        """The mask of every slot (sb3-contrib's MaskablePPO reads it)."""
        return self._masks.copy()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        if attr_name in ("action_masks", "render_mode"):
            return [getattr(self, attr_name) for _ in self._indices(indices)]
        return [getattr(self._env_of(i), attr_name) for i in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for i in self._indices(indices):
            setattr(self._env_of(i), attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        slots = self._indices(indices)
        if method_name == "action_masks":  # per slot, as sb3-contrib's get_action_masks stacks them
            return [self._masks[i].copy() for i in slots]
        return [getattr(self._env_of(i), method_name)(*method_args, **method_kwargs) for i in slots]

    def env_is_wrapped(
        self,
        wrapper_class: type[gym.Wrapper[Any, Any, Any, Any]],
        indices: VecEnvIndices = None,
    ) -> list[bool]:
        return [False for _ in self._indices(indices)]

    # -- helpers ---------------------------------------------------------------------------------
    def _indices(self, indices: VecEnvIndices) -> Sequence[int]:
        return list(self._get_indices(indices))

    def _env_of(self, slot: int) -> Any:
        return self.envs[slot // len(self.robots)]

    def _take(
        self, e: int, obs: Mapping[str, Any], infos: Mapping[str, Mapping[str, Any]]
    ) -> np.ndarray:
        """The slots of copy `e`: observation rows, and their masks stored."""
        n = len(self.robots)
        for i, r in enumerate(self.robots):
            self._masks[e * n + i] = infos[r]["action_mask"].astype(bool)
        return np.stack([obs[r] for r in self.robots]).astype(np.float32)
