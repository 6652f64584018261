"""Gymnasium ids for the single-robot view (`SingleRobotEnv`), so that `gymnasium.make(id)` and
`gymnasium.make_vec(id, num_envs, vectorization_mode="sync" | "async")` build it.

Importing `tavc_agents.envs` registers `SINGLE_ROBOT_IDS`, one id per scenario of the suite;
`gymnasium.make("tavc/dahl2004-v0")` then works (or, without that import, `gymnasium.make("tavc_agents.envs:tavc/dahl2004-v0")`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium

from tavc_env.scenarios import SCENARIOS

SINGLE_ROBOT_ENTRY_POINT = "tavc_agents.envs.single_robot:SingleRobotEnv"

SINGLE_ROBOT_IDS: Mapping[str, Mapping[str, Any]] = {
    s.id: {"scenario": s.name} for s in SCENARIOS.values()
}
"""Gymnasium id -> `SingleRobotEnv` keyword arguments: every scenario of the suite
(`tavc_env.scenarios`), under the id it has in PettingZoo's registry."""


def register_single_robot_envs(ids: Mapping[str, Mapping[str, Any]]) -> None:
    """Register every `id -> kwargs` of `ids` in Gymnasium's registry as the single-robot view
    with those keyword arguments. Registering an id again with the same arguments does nothing;
    with other arguments (or another entry point) it is a ValueError naming the id, since
    Gymnasium would only warn and replace it."""
    for env_id, kwargs in ids.items():
        wanted = dict(kwargs)
        known = gymnasium.registry.get(env_id)
        if known is None:
            gymnasium.register(env_id, entry_point=SINGLE_ROBOT_ENTRY_POINT, kwargs=wanted)
        elif known.entry_point != SINGLE_ROBOT_ENTRY_POINT or dict(known.kwargs) != wanted:
            raise ValueError(
                f"gymnasium id {env_id!r} = {known.entry_point} with {dict(known.kwargs)!r} is "
                f"invalid here; allowed: unregistered, or {SINGLE_ROBOT_ENTRY_POINT} with {wanted!r}"
            )
