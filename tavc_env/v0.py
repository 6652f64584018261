"""`tavc_arena_v0`, kept for saved work: the v1 arena with v0's infos.

v0's infos differ from v1's in two values: `phase` is a name ("deciding", "to_source", "to_sink",
"broken") and `task_time_s` is None when the robot completed no task in the step. Observations
are always the paper's (`observation_mode="paper"`, `observation_format="dict"`); trajectories are
v1's, bit for bit.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from pettingzoo.utils.env import AECEnv

from tavc_env.env import PHASES, TavcArenaEnv, aec_view, completed_task_s
from tavc_env.validation import require

ENV_NAME_V0 = "tavc_arena_v0"


class TavcArenaEnvV0(TavcArenaEnv):
    """`TavcArenaEnv` with v0's infos (see the module's docstring); the same arguments, except
    that the observation mode and format are v0's only."""

    metadata: ClassVar[dict[str, Any]] = {**TavcArenaEnv.metadata, "name": ENV_NAME_V0}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        for name, v0 in (("observation_mode", "paper"), ("observation_format", "dict")):
            value = getattr(self.options, name)
            require(
                value == v0, name, value, f"{v0!r} (v0 has no other; use tavc_env.parallel_env)"
            )

    def _infos(
        self, truncated: bool, deciding: np.ndarray | None = None
    ) -> dict[str, dict[str, Any]]:
        infos = super()._infos(truncated, deciding)
        for info in infos.values():
            info["phase"] = PHASES[info["phase"]]
            info["task_time_s"] = completed_task_s(info)
            del info["task_completed"]
        return infos


def parallel_env(**kwargs: Any) -> TavcArenaEnvV0:
    """The v0 arena as a PettingZoo ParallelEnv (arguments: `TavcArenaEnv`'s)."""
    return TavcArenaEnvV0(**kwargs)


def env(**kwargs: Any) -> AECEnv[str, dict[str, np.ndarray], int | None]:
    """The v0 arena as a PettingZoo AEC env."""
    return aec_view(parallel_env(**kwargs))
