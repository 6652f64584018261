"""The scenario suite: arenas with an episode schedule and an evaluation protocol, each a versioned
id in PettingZoo's registry (`tavc/<name>-v<version>`).

A `Scenario` is data: an arena (a preset and overrides of it, including where the robots start),
an episode schedule (its length and, in dynamic scenarios, seeded priority shifts; breakdowns are
part of the arena) and an evaluation protocol (fixed evaluation seeds and the metric,
`METRIC`). `ScenarioEnv` is the arena env that plays the schedule. Each scenario's references
(random, `stay` and the model optimum) are measured and committed by the `scenarios` study of
`tavc_agents` (`benchmarks/scenarios.py`, `docs/results/scenarios.md`); why each scenario is what
it is, is said in `SCENARIOS` beside it.

    import pettingzoo, tavc_env
    env = pettingzoo.make("parallel", "tavc/priority_shifts-v0")
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
from pettingzoo.utils.env import AECEnv

from tavc_env.config import ArenaConfig, Breakdown, make_config
from tavc_env.env import TavcArenaEnv, aec_view
from tavc_env.options import OPTION_KEYS, EnvOptions
from tavc_env.safe_files import read_json
from tavc_env.validation import is_integer, is_number, require

REFERENCES_FILE = "data/scenario_references.json"
"""The scenarios' committed references (package data, beside this module): value per hour of
random allocation, `stay` and the model optimum on each scenario's evaluation seeds, by id."""

METRIC = "value_per_hour"
"""The evaluation metric of every scenario: delivered value per simulated hour over the whole
episode, each delivery counting the value `w_i` its circuit had when it was delivered."""

EVAL_SEEDS = tuple(range(10_000, 10_020))
"""The evaluation seeds every scenario uses (train on others)."""


@dataclass(frozen=True)
class ValueShifts:
    """Priority shifts: the circuits' values cycle through `profiles` (one value per circuit each),
    each held for a phase whose length is drawn uniformly from `phase_s = (shortest, longest)` by
    the episode's generator at reset. The first phase has `profiles[0]`, the arena's own values."""

    profiles: tuple[tuple[float, ...], ...]
    phase_s: tuple[float, float]

    def __post_init__(self) -> None:
        ok = (
            isinstance(self.profiles, tuple)
            and len(self.profiles) >= 2
            and all(
                isinstance(p, tuple) and len(p) == len(self.profiles[0]) and len(p) >= 1
                for p in self.profiles
            )
            and all(is_number(w) and w > 0 for p in self.profiles for w in p)
        )
        require(
            ok,
            "value_shifts.profiles",
            self.profiles,
            "a tuple of >= 2 profiles, each a tuple of one value > 0 per circuit",
        )
        lo_hi = self.phase_s
        ok = (
            isinstance(lo_hi, tuple)
            and len(lo_hi) == 2
            and all(is_number(t) for t in lo_hi)
            and 0 < lo_hi[0] <= lo_hi[1]
        )
        require(
            ok,
            "value_shifts.phase_s",
            lo_hi,
            "(shortest, longest) phase, 0 < shortest <= longest s",
        )

    def plan(
        self, rng: np.random.Generator, episode_s: float
    ) -> list[tuple[float, tuple[float, ...]]]:
        """The value changes of one episode: `(at_s, values)` for every phase after the first
        that starts before `episode_s`."""
        changes: list[tuple[float, tuple[float, ...]]] = []
        at = 0.0
        k = 0
        while True:
            at += float(rng.uniform(*self.phase_s))
            k += 1
            if at >= episode_s:
                return changes
            changes.append((at, self.profiles[k % len(self.profiles)]))


@dataclass(frozen=True)
class Scenario:
    """One scenario of the suite (see the module's docstring).

    `arena` holds overrides of the preset as `make_config` takes them (`values`, `start_circuits`,
    `breakdowns`, ...), given as a mapping and kept as sorted `(key, value)` pairs. `model` names the measured TAVC model whose optimum is the scenario's
    reference (a preset's model, shipped with `tavc_agents`; the arena's overrides of values and
    breakdowns are applied to it). `headroom_exempt` marks the paper's own arena, kept as the
    reproduction whatever its headroom.
    """

    name: str
    version: int
    summary: str
    preset: str
    model: str
    arena: Mapping[str, Any] | tuple[tuple[str, Any], ...] = ()
    value_shifts: ValueShifts | None = None
    episode_s: float = 8 * 3600.0
    eval_seeds: tuple[int, ...] = EVAL_SEEDS
    headroom_exempt: bool = False

    def __post_init__(self) -> None:
        require(
            isinstance(self.name, str) and self.name.isidentifier(),
            "scenario.name",
            self.name,
            "an identifier (letters, digits, _)",
        )
        require(
            is_integer(self.version) and self.version >= 0, "scenario.version", self.version, ">= 0"
        )
        require(
            is_number(self.episode_s) and self.episode_s > 0,
            "scenario.episode_s",
            self.episode_s,
            "a duration > 0 s",
        )
        require(
            isinstance(self.eval_seeds, tuple)
            and len(self.eval_seeds) >= 1
            and all(is_integer(s) and s >= 0 for s in self.eval_seeds),
            "scenario.eval_seeds",
            self.eval_seeds,
            "a non-empty tuple of integer seeds >= 0",
        )
        # kept as (key, value) pairs: immutable, and copied and pickled with the env
        pairs = self.arena.items() if isinstance(self.arena, Mapping) else self.arena
        object.__setattr__(self, "arena", tuple(sorted(dict(pairs).items())))
        config = self.config()  # the arena must build
        if self.value_shifts is not None:
            first = self.value_shifts.profiles[0]
            values = tuple(c.value for c in config.circuits)
            require(
                len(first) == config.n_circuits and first == values,
                "scenario.value_shifts.profiles[0]",
                first,
                f"the arena's own circuit values {values}",
            )

    @property
    def id(self) -> str:
        """The registry id, `tavc/<name>-v<version>`."""
        return f"tavc/{self.name}-v{self.version}"

    def config(self) -> ArenaConfig:
        """The scenario's arena."""
        return make_config(self.preset, **dict(self.arena))

    @property
    def references(self) -> References | None:
        """The scenario's committed references (None for a scenario of your own, or a version
        that has none)."""
        return scenario_references().get(self.id)

    def score(self, value_per_hour: float) -> float:
        """`value_per_hour` normalised between random allocation (0) and the model optimum (1);
        a ValueError for a scenario without references."""
        refs = self.references
        require(refs is not None, "scenario", self.id, "a scenario with committed references")
        assert refs is not None
        return (value_per_hour - refs.random_per_h) / (refs.optimum_per_h - refs.random_per_h)


@dataclass(frozen=True)
class References:
    """What a scenario's scores are normalised with: value per simulated hour of random
    allocation, of `stay` and of the model optimum, over `seeds` evaluation seeds."""

    random_per_h: float
    stay_per_h: float
    optimum_per_h: float
    seeds: int


@functools.cache
def scenario_references() -> Mapping[str, References]:
    """Every scenario's committed references by id (`REFERENCES_FILE`, package data)."""
    path = Path(__file__).parent / REFERENCES_FILE
    data = read_json(path, 1 << 20, "the scenarios' references")
    return MappingProxyType(
        {
            id_: References(
                **{k: v[k] for k in ("random_per_h", "stay_per_h", "optimum_per_h", "seeds")}
            )
            for id_, v in data["references"].items()
        }
    )


# The suite. Each entry says why it is built so (DESIGN.md section 7 and docs/results/scenarios.md
# give the model's prediction and the physics' references). The robots of `dahl2004` are
# robot_0-2 fast (0.30 m/s) and robot_3-5 slow (0.20 m/s); circuit 0 is worth 2200, circuit 1 2000.
SCENARIOS: Mapping[str, Scenario] = MappingProxyType(
    {
        s.name: s
        for s in (
            Scenario(
                name="dahl2004",
                version=0,
                summary="The paper's arena and start (an even spread drawn at reset): the "
                "reproduction, whatever its headroom.",
                preset="dahl2004",
                model="dahl2004",
                headroom_exempt=True,
            ),
            Scenario(
                name="passing",
                version=0,
                summary="The passing arena (robots overtake; two bays; 120 s loading), every "
                "robot starting on the low-value circuit: they must spread out.",
                preset="dahl2004_passing",
                model="dahl2004_passing",
                arena={"start_circuits": (1,) * 6},
            ),
            Scenario(
                name="bad_start",
                version=0,
                summary="The paper's arena, started crowded on the low-value circuit: all three "
                "fast robots and two slow ones there, one slow robot alone on the high one.",
                preset="dahl2004",
                model="dahl2004",
                arena={"start_circuits": (1, 1, 1, 0, 1, 1)},
            ),
            Scenario(
                name="priority_shifts",
                version=0,
                summary="Short docks (6 s / 2 s), where a circuit takes more robots before it "
                "saturates; the values swap between 4000 / 1000 and 1000 / 4000 in phases of "
                "1.5-2.5 h drawn at reset.",
                preset="dahl2004_light_stations",
                model="dahl2004_light_stations",
                arena={"values": (4000.0, 1000.0)},
                value_shifts=ValueShifts(
                    profiles=((4000.0, 1000.0), (1000.0, 4000.0)), phase_s=(5400.0, 9000.0)
                ),
            ),
            Scenario(
                name="breakdowns",
                version=0,
                summary="Vacancy chains: three circuits worth 3000 / 2000 / 1000, each class "
                "on its own circuit (fast on the best); the three fast robots break down at "
                "1 h and are repaired at 7 h, leaving the best circuit empty unless others "
                "move up.",
                preset="three_circuits_three_classes",
                model="three_circuits_three_classes",
                arena={
                    "values": (3000.0, 2000.0, 1000.0),
                    "start_circuits": (0, 0, 0, 1, 1, 1, 2, 2, 2),
                    "breakdowns": tuple(
                        Breakdown(robot=i, at_s=3600.0, repair_after_s=6 * 3600.0) for i in range(3)
                    ),
                },
            ),
            Scenario(
                name="three_circuits",
                version=0,
                summary="Three circuits (2200 / 2000 / 1800) and three speed classes, every "
                "robot starting on the two low-value circuits, the fast ones on the lowest.",
                preset="three_circuits_three_classes",
                model="three_circuits_three_classes",
                arena={"start_circuits": (2, 2, 2, 1, 1, 1, 2, 2, 1)},
            ),
            Scenario(
                name="large_team",
                version=0,
                summary="24 robots (fast and slow alternating) on eight circuits worth 2200 "
                "down to 2130, every robot starting on the four low-value ones (three fast "
                "and three slow on each): half the circuits to fill.",
                preset="large_team",
                model="large_team",
                arena={"start_circuits": tuple(4 + (i // 2) % 4 for i in range(24))},
            ),
        )
    }
)


def scenario_named(name: str | Scenario) -> Scenario:
    """The scenario `name` (a key of `SCENARIOS`), or `name` itself if it is a `Scenario`."""
    if isinstance(name, Scenario):
        return name
    require(
        isinstance(name, str) and name in SCENARIOS, "scenario", name, f"one of {sorted(SCENARIOS)}"
    )
    return SCENARIOS[name]


class ScenarioEnv(TavcArenaEnv):
    """A scenario's arena as a PettingZoo `ParallelEnv`: its arena, its priority shifts (drawn at
    every reset from the reset's generator) and, unless `options` or `max_sim_time_s` say
    otherwise, episodes of its length.

    Args:
        scenario: a name in `SCENARIOS`, or a `Scenario`.
        options: the env's `EnvOptions` (None: the defaults with `max_sim_time_s` the scenario's
            episode length).
        **option_overrides: fields of `EnvOptions` changed from `options`. The arena is the
            scenario's: to change it, build a `Scenario` of your own.
    """

    def __init__(
        self,
        scenario: str | Scenario = "dahl2004",
        options: EnvOptions | None = None,
        **option_overrides: Any,
    ) -> None:
        chosen = scenario_named(scenario)
        arena_keys = sorted(k for k in option_overrides if k not in OPTION_KEYS)
        require(
            not arena_keys,
            "scenario env arguments",
            arena_keys,
            f"env options only ({sorted(OPTION_KEYS)}): a scenario's arena is fixed "
            "(build a tavc_env.scenarios.Scenario of your own to change it)",
        )
        base = options if options is not None else EnvOptions(max_sim_time_s=chosen.episode_s)
        super().__init__(config=chosen.config(), options=base, **option_overrides)
        self.scenario = chosen

    def episode_statistics(self) -> dict[str, float]:
        """The arena env's episode statistics and, for a scenario with committed references, the
        episode's normalised score (`Scenario.score`: 0 random allocation, 1 the model optimum)."""
        stats = super().episode_statistics()
        if self.scenario.references is not None and stats["sim_time_s"] > 0:
            stats["score"] = self.scenario.score(stats["value_per_hour"])
        return stats

    def _plan_values(self, rng: np.random.Generator) -> list[tuple[float, tuple[float, ...]]]:
        shifts = self.scenario.value_shifts
        if shifts is None:
            return []
        # on the physics step's grid: simulated time advances a step at a time
        dt = self.config.dt
        return [
            (math.ceil(at / dt - 1e-9) * dt, values)
            for at, values in shifts.plan(rng, self.options.max_sim_time_s)
        ]


def parallel_env(scenario: str | Scenario = "dahl2004", **kwargs: Any) -> ScenarioEnv:
    """The scenario as a PettingZoo ParallelEnv (arguments: `ScenarioEnv`'s)."""
    return ScenarioEnv(scenario, **kwargs)


def env(
    scenario: str | Scenario = "dahl2004", **kwargs: Any
) -> AECEnv[str, dict[str, np.ndarray], int | None]:
    """The scenario as a PettingZoo AEC env."""
    return aec_view(parallel_env(scenario, **kwargs))
