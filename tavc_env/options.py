"""The env's own options, as one frozen, validated dataclass beside the arena's `ArenaConfig`.

An `ArenaConfig` says what the arena is (geometry, robots, stations, physics step); `EnvOptions` say
how an env presents it to learners: episode limits, stepping, reward unit, jam window, observations
and rendering. `resolve_env_args` is the one place where the keyword arguments of
`tavc_env.parallel_env` (a preset or a config, arena overrides, options) become the two.

    options = EnvOptions(decision_interval_s=5.0, observation_mode="paper_id")
    env = tavc_env.parallel_env(preset="dahl2004", options=options, source_service_s=10.0)
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tavc_env.config import ARENA_KEYS, JAM_WINDOW_S, ArenaConfig, make_config
from tavc_env.observations import check_observation_args
from tavc_env.validation import is_integer, is_number, require, shown

RENDER_MODES = ("human", "rgb_array")
TIME_UNITS = {"ms": 1000.0, "s": 1.0}
AGENT_NAMES = ("index", "speed_class")
# A speed-class label usable as an agent-name prefix: TorchRL and BenchMARL group agents by the part
# of the name before its first "_", so a label must not contain one
_CLASS_LABEL = re.compile(r"[A-Za-z][A-Za-z0-9-]*")
# What a delivery on circuit i pays: the paper's w_i / t, or w_i itself (whose undiscounted return,
# summed over robots, is the delivered value: docs/semi_mdp.md)
REWARDS = ("paper", "value")


@dataclass(frozen=True)
class EnvOptions:
    """How an env presents its arena (checked on construction; what depends on the arena's
    physics step is checked against it by `check`).

    Args:
        max_cycles: truncate after this many `step` calls.
        max_sim_time_s: truncate when simulated time reaches this (default 24 h; math.inf: never).
        decision_interval_s: None for event-driven stepping, else the fixed simulated time per step
            (a whole number of physics steps).
        reward_time_unit: "ms" (default, the paper's scale) or "s" for t in `w / t`.
        reward: what a delivery on circuit i pays: "paper" (default, Equation 2: `w_i / t`) or
            "value" (`w_i`, so that the robots' undiscounted returns add up to the delivered
            value; `reward_time_unit` plays no part). See docs/semi_mdp.md.
        step_cap_s: event-driven steps return after at most this much simulated time.
        jam_window_s: the jam detector's window: no task event for this long while no moving
            robot gets 1 m from where it was is a jam, reported as `jammed` in every info
            (math.inf: off).
        observation_mode: "paper" (default: the paper's one-hot), "paper_id" or "rich" (see
            `tavc_env.observations` for what each reveals).
        observation_format: "dict" (observation + action_mask) or "box" (the vector alone).
        render_mode: None, "human" or "rgb_array".
        agent_names: "index" (default: `robot_0 .. robot_{n-1}`) or "speed_class" (each robot's
            `speed_class` label and its number within the class, in robot order: `fast_0, fast_1,
            fast_2, slow_0, ...`, which TorchRL and BenchMARL group by class). Either way
            `possible_agents[i]` is robot `i`.
    """

    max_cycles: int = 100_000
    max_sim_time_s: float = 24 * 3600.0
    decision_interval_s: float | None = None
    reward_time_unit: str = "ms"
    reward: str = "paper"
    step_cap_s: float = 600.0
    jam_window_s: float = JAM_WINDOW_S
    observation_mode: str = "paper"
    observation_format: str = "dict"
    render_mode: str | None = None
    agent_names: str = "index"

    def __post_init__(self) -> None:
        check_observation_args(self.observation_mode, self.observation_format)
        require(
            self.render_mode is None or self.render_mode in RENDER_MODES,
            "render_mode",
            self.render_mode,
            f"None or one of {list(RENDER_MODES)}",
        )
        require(
            is_integer(self.max_cycles) and self.max_cycles >= 1,
            "max_cycles",
            self.max_cycles,
            "an integer >= 1",
        )
        require(
            self.max_sim_time_s == math.inf
            or (is_number(self.max_sim_time_s) and self.max_sim_time_s > 0),
            "max_sim_time_s",
            self.max_sim_time_s,
            "a time >= one physics step of the arena (its dt), or math.inf",
        )
        interval = self.decision_interval_s
        require(
            interval is None or (is_number(interval) and interval > 0),
            "decision_interval_s",
            interval,
            "None (event-driven) or a finite time > 0 s (a whole number of physics steps)",
        )
        require(
            isinstance(self.reward_time_unit, str) and self.reward_time_unit in TIME_UNITS,
            "reward_time_unit",
            self.reward_time_unit,
            str(list(TIME_UNITS)),
        )
        require(
            isinstance(self.reward, str) and self.reward in REWARDS,
            "reward",
            self.reward,
            f"{list(REWARDS)} (paper: w_i / t per delivery; value: w_i per delivery)",
        )
        require(
            is_number(self.step_cap_s) and self.step_cap_s > 0,
            "step_cap_s",
            self.step_cap_s,
            "a finite time >= one physics step of the arena (its dt)",
        )
        require(
            self.jam_window_s == math.inf
            or (is_number(self.jam_window_s) and self.jam_window_s > 0),
            "jam_window_s",
            self.jam_window_s,
            "a time > 0 s, or math.inf (no jam detection)",
        )
        require(
            isinstance(self.agent_names, str) and self.agent_names in AGENT_NAMES,
            "agent_names",
            self.agent_names,
            str(list(AGENT_NAMES)),
        )
        object.__setattr__(self, "max_cycles", int(self.max_cycles))
        object.__setattr__(self, "max_sim_time_s", float(self.max_sim_time_s))
        object.__setattr__(self, "step_cap_s", float(self.step_cap_s))
        object.__setattr__(self, "jam_window_s", float(self.jam_window_s))

    def check(self, config: ArenaConfig) -> None:
        """A ValueError naming the option unless the times fit `config`'s physics step: at least
        one step, at most what a float resolves (`ArenaConfig.max_time_s`), and a fixed decision
        interval a whole number of steps within the episode."""
        dt = config.dt
        longest = config.max_time_s
        resolved = f"at most {longest:.4g} s, beyond which a float no longer resolves dt / 1e6"
        limit = self.max_sim_time_s
        require(
            limit == math.inf or dt <= limit <= longest,
            "max_sim_time_s",
            limit,
            f"a time >= one physics step ({dt} s) and {resolved}, or math.inf",
        )
        interval = self.decision_interval_s
        if interval is not None:
            steps = interval / dt
            require(
                steps >= 1 - 1e-9 and abs(steps - round(steps)) < 1e-6,
                "decision_interval_s",
                interval,
                "None (event-driven) or a finite whole number of physics steps "
                f"(multiples of dt = {dt} s)",
            )
            require(
                interval <= min(limit, longest) * (1 + 1e-9),
                "decision_interval_s",
                interval,
                f"an interval of at most max_sim_time_s = {limit:g} s (a longer one "
                "would end the episode at its first step)"
                if limit != math.inf
                else f"an interval {resolved}",
            )
        require(
            dt <= self.step_cap_s <= longest,
            "step_cap_s",
            self.step_cap_s,
            f"a finite time >= one physics step ({dt} s) and {resolved}",
        )
        if self.agent_names == "speed_class":
            for i, robot in enumerate(config.robots):
                require(
                    _CLASS_LABEL.fullmatch(robot.speed_class) is not None,
                    "agent_names",
                    self.agent_names,
                    f"'index', or 'speed_class' with every robot labelled by a letter then letters, "
                    f"digits or '-' (no '_': libraries group agents by the name before its first "
                    f"'_'); robots[{i}].speed_class is {robot.speed_class!r}",
                )

    def changed(self) -> dict[str, Any]:
        """The options that differ from their defaults, by name (what a record of a run needs)."""
        return {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if getattr(self, f.name) != f.default
        }

    def replace(self, **changes: Any) -> EnvOptions:
        """A copy with options changed (validated again)."""
        return dataclasses.replace(self, **changes)


OPTION_KEYS = tuple(f.name for f in dataclasses.fields(EnvOptions))


class UnknownOptionError(TypeError, ValueError):
    """`EnvOptions` given a field it does not have (a TypeError, as Python's own for an unexpected
    keyword, and a ValueError, as the package's other refusals)."""


def _refuse_unknown_fields(init: Any) -> Any:
    """`EnvOptions.__init__`, refusing a keyword that is not a field with a message naming it and
    every field (the dataclass's own says only "unexpected keyword argument")."""

    @functools.wraps(init)
    def checked(self: EnvOptions, *args: Any, **kwargs: Any) -> None:
        unknown = [k for k in kwargs if k not in OPTION_KEYS]
        if unknown:
            given = ", ".join(f"{k}={shown(kwargs[k])}" for k in unknown)
            arena = [k for k in unknown if k in ARENA_KEYS]
            hint = (
                f" ({', '.join(arena)}: an arena field, for ArenaConfig or the env's keywords)"
                if arena
                else ""
            )
            raise UnknownOptionError(
                f"EnvOptions({given}) is invalid: no such option{'s' if len(unknown) > 1 else ''}"
                f"{hint}; allowed: {', '.join(OPTION_KEYS)}"
            )
        init(self, *args, **kwargs)

    return checked


setattr(EnvOptions, "__init__", _refuse_unknown_fields(EnvOptions.__init__))  # noqa: B010


def agent_names(config: ArenaConfig, scheme: str = "index") -> list[str]:
    """The agent names of `config`'s robots under the `agent_names` option `scheme`, in robot
    order (checked by `EnvOptions.check`)."""
    if scheme == "index":
        return [f"robot_{i}" for i in range(config.n_robots)]
    seen: dict[str, int] = {}
    names = []
    for robot in config.robots:
        k = seen.get(robot.speed_class, 0)
        seen[robot.speed_class] = k + 1
        names.append(f"{robot.speed_class}_{k}")
    return names


def split_env_kwargs(kwargs: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """`kwargs` (arena overrides and env options, mixed as `parallel_env` takes them) split into
    the arena's and the options', in their order; a key that is neither is a ValueError naming
    it and listing both."""
    unknown = sorted(str(k) for k in kwargs if k not in ARENA_KEYS and k not in OPTION_KEYS)
    if unknown:
        raise ValueError(
            f"unknown configuration key(s) {unknown}: neither an arena field (tavc_env.ArenaConfig, or "
            f"the shorthands speeds and values) nor an env option (tavc_env.EnvOptions); "
            f"allowed: arena fields {sorted(ARENA_KEYS)}; env options {list(OPTION_KEYS)}"
        )
    arena = {k: v for k, v in kwargs.items() if k in ARENA_KEYS}
    options = {k: v for k, v in kwargs.items() if k in OPTION_KEYS}
    return arena, options


def resolve_env_args(
    preset: str | None = None,
    config: ArenaConfig | None = None,
    options: EnvOptions | None = None,
    **overrides: Any,
) -> tuple[ArenaConfig, EnvOptions]:
    """The arena and the options that `tavc_env.parallel_env`'s arguments describe: a preset (by
    default `dahl2004`) or a `config` (not both), `options`, and keyword overrides of either
    (arena fields, or options changed from `options`), all checked."""
    require(
        options is None or isinstance(options, EnvOptions),
        "options",
        options,
        "a tavc_env.EnvOptions or None",
    )
    arena, changes = split_env_kwargs(overrides)
    base = options if options is not None else EnvOptions()
    chosen = base.replace(**changes) if changes else base
    resolved = make_config(preset, config, **arena)
    chosen.check(resolved)
    return resolved, chosen
