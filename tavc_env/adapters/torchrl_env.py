"""The arena as a TorchRL-native batched env: `K` arenas of one scenario in this process, one
`EnvBase` with `batch_size=[K]`, every robot's entries stacked `(K, n_robots, ...)`.

    env = TorchArenaEnv(16, env_kwargs={"scenario": "bad_start", "reward": "value"}, seed=0)
    check_env_specs(env)                       # TorchRL's own check
    collector = Collector(env, policy, frames_per_batch=16 * 256)

Each arena is built through the package's one door (`tavc_env.arena.make_env`) and seeded from one
seed as `BatchedArenaEnv` seeds its arenas (`numpy.random.SeedSequence(seed).spawn(K)`): arena `k`
is reset with the `k`-th child seed the first time, then continues its own generator, so the
same seed gives the same batch of trajectories. A step runs each arena through the arena part of
the env's step (`ArenaEnv.advance_choices`) and builds every robot's entries for all arenas at once
from the engines' arrays (`tavc_env.env.arena_arrays`, as the batched view does), with no
per-agent dicts:

- `("robot", "observation")` `(K, n, k)` float32: the env's observation vector (`paper_id` by
  default, so that a shared network tells the robots apart);
- `("robot", "action_mask")` `(K, n, m)` bool: all circuits for a robot that decides, else only
  the one it serves (docs/semi_mdp.md: its action is ignored);
- `("robot", "decides")` `(K, n)` bool: `info["action_required"]`, the rows a learner trains on;
- `("robot", "epoch")` `(K, n)` bool: the observation is the robot's decision epoch, which ends
  its previous decision's sojourn: `decides`, and at truncation also a robot that delivered in
  the last step (its transition is complete; one still on its task has none, docs/semi_mdp.md);
- `("robot", "elapsed_s")` `(K, n, 1)` float32: simulated seconds since the robot's last decision
  (at an epoch: the sojourn time tau of the decision before, for discounting by gamma ** tau);
- `("robot", "index")` `(K, n)` int64: the robot's index (for per-robot or per-class parameters);
- `("robot", "reward")` `(K, n, 1)` float32: each robot's reward of the step;
- `"state"` `(K, s)` float32: each arena's `env.state()`, for a centralised critic;
- `done`, `terminated`, `truncated` `(K, 1)` bool: a whole arena ends at once (at its time limit:
  `truncated`; the task is continuing, so `terminated` is always False).

The action is `("robot", "action")` `(K, n)` int64; only deciding robots' entries are read. An
arena that ends is reset by TorchRL (a `Collector`, `rollout`), through the `"_reset"` key: only
the arenas it flags are reset. Needs the `marl` extra (torch, TorchRL).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

try:
    import torch
    from tensordict import TensorDict, TensorDictBase
    from torchrl.data import Binary, Bounded, Categorical, Composite, Unbounded
    from torchrl.envs import EnvBase
except ImportError as exc:  # an optional extra: say which
    raise ImportError(
        "tavc_env.adapters.torchrl_env needs torch and TorchRL: install the `marl` extra "
        "(pip install 'tavc-env[marl]'; docs/tutorials/deep_marl.md for the CPU build of torch)"
    ) from exc

from tavc_env.adapters.batched import (
    advance_arenas,
    arena_seeds,
    require_batch,
    require_circuits,
)
from tavc_env.arena import make_env
from tavc_env.env import ArenaEnv, arena_arrays
from tavc_env.validation import is_integer, require

GROUP = "robot"
"""The key of the robots' entries (`(GROUP, "observation")`, ...)."""
DEFAULT_ENV_KWARGS: Mapping[str, Any] = {
    "observation_mode": "paper_id",
    "observation_format": "dict",
}
"""Env arguments every arena gets unless `env_kwargs` says otherwise."""


class TorchArenaEnv(EnvBase):
    """`n_envs` arenas of one kind stepped in this process as one TorchRL env (see the module's
    docstring for the keys).

    Args:
        n_envs: arenas in the batch (`K`), at most `tavc_env.adapters.batched.MAX_ENVS`.
        env_kwargs: arguments of `tavc_env.arena.make_env` (a `scenario` or a `preset`, arena
            overrides, env options such as `reward="value"`, `max_sim_time_s`), over
            `DEFAULT_ENV_KWARGS`; `observation_format` must stay "dict".
        seed: the batch's seed (None: set one later with `set_seed`, or fresh entropy).
        with_state: include `"state"` (every step pays `env.state()`, about 30 us per arena;
            an IPPO learner does without it).
    """

    batch_locked = True

    def __init__(
        self,
        n_envs: int,
        *,
        env_kwargs: Mapping[str, Any] | None = None,
        seed: int | None = None,
        with_state: bool = True,
    ) -> None:
        require_batch(n_envs, env_kwargs)
        require(
            seed is None or (is_integer(seed) and seed >= 0),
            "seed",
            seed,
            "None or an integer >= 0",
        )
        super().__init__(batch_size=torch.Size([int(n_envs)]), device="cpu")
        kwargs = {**DEFAULT_ENV_KWARGS, **(env_kwargs or {})}
        require(
            kwargs["observation_format"] == "dict",
            "env_kwargs['observation_format']",
            kwargs["observation_format"],
            '"dict" (the default here; the mask is read from the observation)',
        )
        self.envs: list[ArenaEnv[Any]] = [make_env(**kwargs) for _ in range(int(n_envs))]
        first = self.envs[0]
        self.agents = list(first.possible_agents)
        self.config = first.config
        self.with_state = bool(with_state)
        n, m, K = len(self.agents), first.config.n_circuits, int(n_envs)
        self.n_robots, self.n_circuits = n, m
        space = first.observation_space(self.agents[0])
        assert isinstance(space, spaces.Dict)  # observation_format="dict"
        width = int(np.prod(space["observation"].shape or (1,)))
        self._make_specs(K, n, m, width, int(first.state_space.shape[0]))
        # the step's arrays, written in place arena by arena, copied into each step's tensors
        self._obs = np.zeros((K, n, width), np.float32)
        self._mask = np.zeros((K, n, m), bool)
        self._decides = np.zeros((K, n), bool)
        self._epoch = np.zeros((K, n), bool)
        self._elapsed = np.zeros((K, n, 1), np.float32)
        self._reward = np.zeros((K, n, 1), np.float32)
        self._state = np.zeros((K, int(first.state_space.shape[0])), np.float32)
        self._truncated = np.zeros((K, 1), bool)
        self._index = torch.arange(n).expand(K, n)
        self._seeds: list[int | None] = [None] * K
        if seed is not None:
            self.set_seed(int(seed))

    # -- specs --------------------------------------------------------------------------------
    def _make_specs(self, K: int, n: int, m: int, width: int, state_width: int) -> None:
        shape = (K, n)
        robots = Composite(
            observation=Bounded(0.0, 1.0, (*shape, width), dtype=torch.float32),
            action_mask=Binary(n=m, shape=(*shape, m), dtype=torch.bool),
            decides=Binary(n=n, shape=shape, dtype=torch.bool),
            epoch=Binary(n=n, shape=shape, dtype=torch.bool),
            elapsed_s=Unbounded((*shape, 1), dtype=torch.float32),
            index=Categorical(n, shape, dtype=torch.int64),
            shape=shape,
        )
        observations = Composite({GROUP: robots}, shape=(K,))
        if self.with_state:
            observations["state"] = Bounded(-1.0, 1.0, (K, state_width), dtype=torch.float32)
        self.observation_spec = observations
        self.action_spec = Composite(
            {
                GROUP: Composite(
                    action=Categorical(m, shape, dtype=torch.int64),
                    shape=shape,
                )
            },
            shape=(K,),
        )
        self.reward_spec = Composite(
            {GROUP: Composite(reward=Unbounded((*shape, 1)), shape=shape)}, shape=(K,)
        )
        flag = Categorical(2, (K, 1), dtype=torch.bool)
        self.done_spec = Composite(
            done=flag, terminated=flag.clone(), truncated=flag.clone(), shape=(K,)
        )

    # -- EnvBase ------------------------------------------------------------------------------
    def _set_seed(self, seed: int | None) -> None:
        """Arena `k`'s next reset uses the `k`-th seed spawned from `seed` (as
        `BatchedArenaEnv.reset(seed)`); later resets continue each arena's generator."""
        self._seeds = list(arena_seeds(seed, len(self.envs)))

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        which = range(len(self.envs))
        if tensordict is not None and "_reset" in tensordict:
            which = np.flatnonzero(tensordict["_reset"].reshape(-1).numpy()).tolist()
        for k in which:
            self.envs[k].reset(seed=self._seeds[k])
            self._seeds[k] = None
        self._truncated[which] = False
        self._read(which)
        return self._output(with_reward=False)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = tensordict[GROUP, "action"].numpy()
        require_circuits(actions, self._decides, self.n_circuits)
        rewards, truncated = advance_arenas(self.envs, actions, self._decides)
        self._reward[:, :, 0] = rewards
        self._truncated[:, 0] = truncated
        self._read(range(len(self.envs)))
        return self._output(with_reward=True)

    # -- helpers -----------------------------------------------------------------------------
    def _read(self, which: Sequence[int]) -> None:
        """Arenas `which`'s step (or reset) results into their rows of the arrays, from the
        engines' arrays (`tavc_env.env.arena_arrays`, as the batched view builds them)."""
        which = list(which)
        if not which:
            return
        envs = [self.envs[k] for k in which]
        truncated = self._truncated[which, 0]
        arrays = arena_arrays(envs, truncated.tolist())
        decides = arrays["action_required"]
        self._obs[which] = arrays["observations"]
        self._decides[which] = decides
        self._epoch[which] = decides | (truncated[:, None] & arrays["task_completed"])
        self._elapsed[which, :, 0] = arrays["elapsed_s"]
        self._mask[which] = arrays["action_mask"].astype(bool) | decides[:, :, None]
        if self.with_state:
            for k, env in zip(which, envs):
                self._state[k] = env.state()

    def _output(self, with_reward: bool) -> TensorDictBase:
        """The arrays as a TensorDict (copies: the collector keeps every step's)."""
        K = len(self.envs)
        robots: dict[str, torch.Tensor] = {
            "observation": torch.from_numpy(self._obs.copy()),
            "action_mask": torch.from_numpy(self._mask.copy()),
            "decides": torch.from_numpy(self._decides.copy()),
            "epoch": torch.from_numpy(self._epoch.copy()),
            "elapsed_s": torch.from_numpy(self._elapsed.copy()),
            "index": self._index.clone(),
        }
        if with_reward:
            robots["reward"] = torch.from_numpy(self._reward.copy())
        truncated = torch.from_numpy(self._truncated.copy())
        out: dict[str, Any] = {
            GROUP: TensorDict(robots, batch_size=(K, self.n_robots)),
            "done": truncated,
            "terminated": torch.zeros_like(truncated),
            "truncated": truncated.clone(),
        }
        if self.with_state:
            out["state"] = torch.from_numpy(self._state.copy())
        return TensorDict(out, batch_size=(K,))

    def close(self, *, raise_if_closed: bool = True) -> None:
        for env in self.envs:
            env.close()
        super().close(raise_if_closed=raise_if_closed)
