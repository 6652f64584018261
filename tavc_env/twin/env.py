"""The model twin as a PettingZoo `ParallelEnv` (`tavc_twin_v0`, see `tavc_env.twin`): the env
adapter of the physics (`tavc_env.env.ArenaEnv`) driving the twin's engine."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from tavc_env.engine.simulation import ArenaSnapshot
from tavc_env.env import ArenaEnv
from tavc_env.observations import N_PHASES
from tavc_env.options import resolve_env_args
from tavc_env.twin.engine import TaskTimeProcess
from tavc_env.twin.tables import InterferenceTables, as_tables
from tavc_env.validation import require

TWIN_ENV_NAME = "tavc_twin_v0"


class TwinArenaEnv(ArenaEnv[TaskTimeProcess]):
    """The arena's decision process as a PettingZoo `ParallelEnv`, with task times drawn from
    `tables` (see `tavc_env.twin`): the env adapter of `TavcArenaEnv` (`ArenaEnv`) driving the
    twin's engine, `TaskTimeProcess`.

    Args:
        tables: the arena's `InterferenceTables` (or their `to_dict()`), for the team and
            circuits of the configuration.
        **env_kwargs: `TavcArenaEnv`'s arguments (`preset` or `config`, `options` and
            overrides of the arena or the options), except that the `EnvOptions`' `render_mode`
            must be None (the twin draws nothing) and `observation_mode` `paper` or `paper_id`;
            `jam_window_s` is accepted, unused (the twin never jams).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": TWIN_ENV_NAME,
        "render_modes": [],
        "render_fps": 10,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        tables: InterferenceTables | Mapping[str, Any],
        **env_kwargs: Any,
    ) -> None:
        tables = as_tables(tables)
        # the env's own arguments and defaults, resolved as the physics env resolves them
        config, options = resolve_env_args(**env_kwargs)
        require(
            options.render_mode is None,
            "render_mode",
            options.render_mode,
            "None (the twin draws nothing)",
        )
        require(
            options.observation_mode != "rich",
            "observation_mode",
            options.observation_mode,
            "'paper' or 'paper_id' (the twin has no positions for 'rich')",
        )
        self.tables = tables
        super().__init__(config=config, options=options)

    def _new_engine(self) -> TaskTimeProcess:
        return TaskTimeProcess(self.config, self.tables)

    def _state_space(self) -> spaces.Box:
        n, m = self.config.n_robots, self.config.n_circuits
        size = n * (m + N_PHASES) + m * len(self.tables.classes)
        return spaces.Box(0.0, 1.0, (size,), np.float32)

    @property
    def process(self) -> TaskTimeProcess:
        """The twin's engine (`sim`, by the name the twin has always given it)."""
        return self.sim

    def state(self) -> np.ndarray:
        """Global state of the twin: per robot [circuit one-hot, phase one-hot]; per circuit and
        class, the robots of that class working on it over the class's robots."""
        if self._rng is None:
            raise ValueError("state() called before reset(); allowed: call reset() first")
        n, m = self.config.n_robots, self.config.n_circuits
        tasks = self.process.tasks
        robots = np.zeros((n, m + N_PHASES), np.float32)
        robots[np.arange(n), tasks.circuit] = 1.0
        robots[np.arange(n), m + np.array(tasks.phase)] = 1.0
        shares = self.process.committed() / np.array(self.tables.team, dtype=float)
        return np.concatenate([robots.ravel(), shares.astype(np.float32).ravel()])

    def snapshot(self) -> ArenaSnapshot:
        raise ValueError(
            "the twin has no arena to take a snapshot of (no positions); allowed: state(), the "
            "infos, or the physics env (tavc_env.parallel_env) for snapshots"
        )
