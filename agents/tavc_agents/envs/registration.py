"""Gymnasium ids for the single-robot view (`SingleRobotEnv`), so that `gymnasium.make(id)` and
`gymnasium.make_vec(id, num_envs, vectorization_mode="sync" | "async")` build it.

The ids and their registration live in `tavc_env.registration` (so that `import tavc_env` alone
registers them, as Gymnasium 1.x has no plugin discovery); they are named here too, beside the view
they build. Importing `tavc_agents.envs` registers them again, which does nothing.
"""

from __future__ import annotations

from tavc_env.registration import (
    SINGLE_ROBOT_ENTRY_POINT,
    SINGLE_ROBOT_IDS,
    register_single_robot_envs,
)

__all__ = ["SINGLE_ROBOT_ENTRY_POINT", "SINGLE_ROBOT_IDS", "register_single_robot_envs"]
