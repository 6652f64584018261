"""tavc-env: the prioritized transportation arena of Dahl, Mataric & Sukhatme (DARS 2004) as a
PettingZoo environment on pymunk physics.

    import tavc_env
    env = tavc_env.parallel_env(preset="dahl2004")
    observations, infos = env.reset(seed=0)

The arena is an `ArenaConfig` (a preset, or `config=`), the env's own options an `EnvOptions`
(`options=`); keyword overrides of either go straight to `parallel_env`. Which arena a caller
means (a scenario or a preset, by name or as a value) is resolved in one place,
`tavc_env.resolve_arena` (`tavc_env.arena`).

`tavc_env.twin_parallel_env(tables=..., preset=...)` is the model twin: the same decision process
with task times drawn from measured interference tables (`tavc_env.twin`), for fast what-if
studies; never a replacement for the physics.
"""

from tavc_env import scenarios
from tavc_env.arena import Arena, resolve_arena
from tavc_env.config import (
    PRESETS,
    ArenaConfig,
    Breakdown,
    Circuit,
    Robot,
    lane_circuits,
    make_config,
    preset,
    robots_from_speeds,
    scaled_config,
)
from tavc_env.engine.simulation import Simulation
from tavc_env.env import (
    ENV_NAME,
    PHASES,
    RecordEpisodeStatistics,
    TavcArenaEnv,
    completed_task_s,
    env,
    parallel_env,
    raw_env,
)
from tavc_env.observations import OBSERVATION_FORMATS, OBSERVATION_MODES
from tavc_env.options import EnvOptions
from tavc_env.registration import REGISTRY_ID, REGISTRY_ID_V0, register
from tavc_env.scenarios import SCENARIOS, Scenario, ScenarioEnv, ValueShifts
from tavc_env.twin import InterferenceTables, TaskTimeCell, TwinArenaEnv, twin_parallel_env

register()

__version__ = "0.2.0"

__all__ = [
    "ENV_NAME",
    "OBSERVATION_FORMATS",
    "OBSERVATION_MODES",
    "PHASES",
    "PRESETS",
    "REGISTRY_ID",
    "REGISTRY_ID_V0",
    "SCENARIOS",
    "Arena",
    "ArenaConfig",
    "Breakdown",
    "Circuit",
    "EnvOptions",
    "InterferenceTables",
    "RecordEpisodeStatistics",
    "Robot",
    "Scenario",
    "ScenarioEnv",
    "Simulation",
    "TaskTimeCell",
    "TavcArenaEnv",
    "TwinArenaEnv",
    "ValueShifts",
    "__version__",
    "completed_task_s",
    "env",
    "lane_circuits",
    "make_config",
    "parallel_env",
    "preset",
    "raw_env",
    "resolve_arena",
    "robots_from_speeds",
    "scaled_config",
    "scenarios",
    "twin_parallel_env",
]
