"""Registration of the arena in PettingZoo's environment registry (PettingZoo >= 1.27 has one).

After `import tavc_env`, `pettingzoo.make("parallel", "tavc/tavc_arena-v1", preset=...)` and
`pettingzoo.make("aec", "tavc/tavc_arena-v1")` build the environments; `tavc/tavc_arena-v0` builds
v0 (`tavc_env.v0`), kept for saved work. Every scenario of the suite (`tavc_env.scenarios`) has an
id of its own, e.g. `pettingzoo.make("parallel", "tavc/priority_shifts-v0")`.

It also puts the single-robot view (`tavc_agents.envs.single_robot.SingleRobotEnv`) in Gymnasium's
registry under the same ids (`SINGLE_ROBOT_IDS`), so `gymnasium.make("tavc/dahl2004-v0")` and
`gymnasium.make_vec(...)` work after `import tavc_env` alone: Gymnasium 1.x has no plugin
discovery, so the ids are registered here with an entry-point string, which Gymnasium imports only
when an env is made (this layer imports nothing of `tavc_agents`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium
import pettingzoo

from tavc_env.scenarios import SCENARIOS, Scenario
from tavc_env.validation import shown

REGISTRY_ID = "tavc/tavc_arena-v1"
REGISTRY_ID_V0 = "tavc/tavc_arena-v0"
_ENTRY_POINTS = {REGISTRY_ID: "tavc_env.env", REGISTRY_ID_V0: "tavc_env.v0"}

SINGLE_ROBOT_ENTRY_POINT = "tavc_agents.envs.single_robot:SingleRobotEnv"
SINGLE_ROBOT_IDS: Mapping[str, Mapping[str, Any]] = {
    s.id: {"scenario": s.name} for s in SCENARIOS.values()
}
"""Gymnasium id -> `SingleRobotEnv` keyword arguments: every scenario of the suite
(`tavc_env.scenarios`), under the id it has in PettingZoo's registry."""


@dataclass(frozen=True)
class ScenarioEntryPoint:
    """What a scenario's PettingZoo id builds: that scenario's env (`view`: "parallel" or "aec").
    PettingZoo passes the id's own `scenario=` overridden by the caller's, so a `scenario=` that
    names another scenario would build it under this id: it is refused, naming the id to use."""

    id: str
    scenario: str
    view: str

    def __call__(self, **kwargs: Any) -> Any:
        from tavc_env import scenarios

        given = kwargs.pop("scenario", self.scenario)
        own = SCENARIOS[self.scenario]
        if not (given == self.scenario or (isinstance(given, Scenario) and given == own)):
            name = given.name if isinstance(given, Scenario) else given
            other = SCENARIOS.get(name) if isinstance(name, str) else None
            use = (
                f"; for scenario {name!r} use the id {other.id!r}"
                if other is not None and (isinstance(given, str) or given == other)
                else ""
            )
            raise ValueError(
                f"scenario = {shown(given)} is invalid for the id {self.id!r}, which is scenario "
                f"{self.scenario!r}; allowed: {self.scenario!r} or no scenario argument{use}"
            )
        make = scenarios.parallel_env if self.view == "parallel" else scenarios.env
        return make(self.scenario, **kwargs)


def register() -> None:
    """Register both views of both versions of the arena, and of every scenario of
    `tavc_env.scenarios.SCENARIOS` (`tavc/<name>-v<version>`), once (none on PettingZoo versions
    without a registry); and the single-robot view of every scenario in Gymnasium's registry
    (`register_single_robot_envs(SINGLE_ROBOT_IDS)`)."""
    register_single_robot_envs(SINGLE_ROBOT_IDS)
    if not hasattr(pettingzoo, "register"):
        return
    for name, module in _ENTRY_POINTS.items():
        if name not in pettingzoo.parallel_registry:
            pettingzoo.register("parallel", name, entry_point=f"{module}:parallel_env")
        if name not in pettingzoo.aec_registry:
            pettingzoo.register("aec", name, entry_point=f"{module}:env")
    for s in SCENARIOS.values():  # the id's scenario is bound: another one is refused
        for view, registry in (
            ("parallel", pettingzoo.parallel_registry),
            ("aec", pettingzoo.aec_registry),
        ):
            if s.id not in registry:
                pettingzoo.register(
                    view,
                    s.id,
                    entry_point=ScenarioEntryPoint(s.id, s.name, view),
                    kwargs={"scenario": s.name},
                )


def register_single_robot_envs(ids: Mapping[str, Mapping[str, Any]]) -> None:
    """Register every `id -> kwargs` of `ids` in Gymnasium's registry as the single-robot view
    with those keyword arguments. Registering an id again with the same arguments does nothing
    (so `tavc_env` and `tavc_agents.envs` may both register, without Gymnasium's warning); with
    other arguments (or another entry point) it is a ValueError naming the id, since Gymnasium
    would only warn and replace it."""
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
