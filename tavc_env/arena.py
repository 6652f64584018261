"""One door to "which arena": a scenario or a preset, by name or as a value, resolved in one place.

Everything that builds an env for a caller (the trial runner, sweeps' `TrialSpec.env_kwargs`, the
`tavc` command, the learning-library adapters) asks this module, so a clash (a scenario together
with a preset, overrides of a scenario's fixed arena) is refused here, once, in one line naming the
values and what is allowed. Like Gymnasium's `make(id, **kwargs)`, one value says which arena:

    arena = resolve_arena("bad_start")              # a scenario of the suite (or its id,
    arena = resolve_arena("tavc/bad_start-v0")      # as in the registries)
    arena = resolve_arena("dahl2004_passing", dt=0.05)  # a preset, with arena overrides
    arena = resolve_arena(my_config)                # an ArenaConfig (or a Scenario of your own)
    arena = resolve_arena({"preset": "dahl2004", "source_service_s": 10.0})  # as plain data
    env = arena.parallel_env(options=EnvOptions(observation_mode="paper_id"))

A name that is both a preset and a scenario (`dahl2004`) is the preset: the plain arena; the
scenario is `tavc/dahl2004-v0` or `{"scenario": "dahl2004"}`. `make_env(**kwargs)` builds the env
from a plain mapping of all of it (a choice, arena overrides and env options mixed), as a
BenchMARL task, an RLlib config or a sweep's trial hold it.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from tavc_env.config import ARENA_KEYS, DEFAULT_PRESET, PRESETS, ArenaConfig, make_config
from tavc_env.env import ArenaEnv, TavcArenaEnv
from tavc_env.options import EnvOptions, split_env_kwargs
from tavc_env.scenarios import SCENARIOS, Scenario, ScenarioEnv
from tavc_env.validation import require

CHOICES = ("scenario", "preset", "config")
"""The keys of a plain mapping that say which arena (at most one of them)."""

ArenaSpec = str | Scenario | ArenaConfig | Mapping[str, Any] | None
"""What `resolve_arena` takes: a scenario or preset name, a scenario id, a `Scenario`, an
`ArenaConfig`, a plain mapping (`{"scenario": ...}`, or `{"preset": ...}` / `{"config": ...}`
with arena overrides), or None (the default preset, with overrides)."""

_ID = re.compile(r"tavc/(?P<name>\w+)-v(?P<version>\d+)")
_ALLOWED = (
    f"a preset ({', '.join(sorted(PRESETS))}), a scenario ({', '.join(sorted(SCENARIOS))}) or its "
    "id (tavc/<name>-v<version>), a tavc_env.Scenario, a tavc_env.ArenaConfig, or a mapping with "
    f"at most one of {list(CHOICES)} and arena overrides"
)


@dataclass(frozen=True)
class Arena:
    """Which arena, resolved: its `config`, the `scenario` it is (None for a plain arena, which
    has no schedule), and `named`, the choice as the caller made it, as plain data (the keyword
    arguments that resolve to it again, as a trial records them: `("scenario", name)`, or
    `("preset", name)` / `("config", config)` then the overrides in their order; nothing for the
    default preset)."""

    config: ArenaConfig
    scenario: Scenario | None
    named: tuple[tuple[str, Any], ...]

    @property
    def kwargs(self) -> dict[str, Any]:
        """`named` as a mapping: what a sweep's `TrialSpec.env_kwargs` holds for this arena."""
        return dict(self.named)

    @property
    def preset(self) -> str | None:
        """The preset the arena is built from (a scenario's too); None for an `ArenaConfig`."""
        if self.scenario is not None:
            return self.scenario.preset
        named = self.kwargs
        return None if "config" in named else str(named.get("preset", DEFAULT_PRESET))

    def parallel_env(
        self,
        options: EnvOptions | None = None,
        factory: Callable[..., ArenaEnv[Any]] | None = None,
        **option_overrides: Any,
    ) -> ArenaEnv[Any]:
        """The arena as a PettingZoo ParallelEnv with `options` (and `option_overrides`): a
        scenario's `ScenarioEnv` (which plays its schedule), else a `TavcArenaEnv`, or what
        `factory` builds from `config=` and the options (e.g. the model twin,
        `functools.partial(tavc_env.twin_parallel_env, tables=...)`; not for a scenario, whose
        schedule needs its own env)."""
        if self.scenario is not None:
            require(
                factory is None,
                "env factory",
                factory,
                f"None for scenario {self.scenario.name!r} (its schedule is played by "
                "tavc_env.ScenarioEnv; another env takes a preset or an ArenaConfig)",
            )
            return ScenarioEnv(self.scenario, options=options, **option_overrides)
        make = TavcArenaEnv if factory is None else factory
        return make(config=self.config, options=options, **option_overrides)


def _named_scenario(scenario: Scenario) -> Any:
    """A scenario as data: its name if it is the suite's, else the `Scenario` itself."""
    return scenario.name if SCENARIOS.get(scenario.name) == scenario else scenario


def resolve_arena(spec: ArenaSpec | Arena = None, **overrides: Any) -> Arena:
    """The arena `spec` names (see the module), with arena `overrides` (fields of
    `tavc_env.ArenaConfig` and the shorthands `speeds`, `values`; a scenario takes none). Every
    clash is a one-line ValueError naming the values and what is allowed."""
    if isinstance(spec, Arena):
        require(not overrides, "arena overrides", sorted(overrides), "none with a resolved Arena")
        return spec
    if isinstance(spec, Mapping):
        plain = dict(spec)
        choice = {k: v for k in CHOICES if (v := plain.pop(k, None)) is not None}
        repeated = sorted(set(plain) & set(overrides))
        require(not repeated, "arena overrides", repeated, "each key once")
        require(
            len(choice) <= 1,
            "arena",
            choice,
            "one of a scenario, a preset or a config (each says which arena; not together)",
        )
        overrides = {**plain, **overrides}
        key, value = next(iter(choice.items())) if choice else ("preset", None)
        allowed = {
            "scenario": f"a scenario ({', '.join(sorted(SCENARIOS))}), its id or a tavc_env.Scenario",
            "preset": f"one of {sorted(PRESETS)}",
            "config": "a tavc_env.ArenaConfig",
        }[key]
        spec = _as_scenario(value) if key == "scenario" else value
        ok = {
            "scenario": spec is not None,
            "preset": value is None or (isinstance(value, str) and value in PRESETS),
            "config": isinstance(value, ArenaConfig),
        }[key]
        require(ok, key, value, allowed)
    elif isinstance(spec, str):
        found = _as_scenario(spec) if spec not in PRESETS else None
        require(spec in PRESETS or found is not None, "arena", spec, _ALLOWED)
        spec = found if found is not None else spec
    else:
        require(spec is None or isinstance(spec, (Scenario, ArenaConfig)), "arena", spec, _ALLOWED)
    not_arena = sorted(str(k) for k in overrides if k not in ARENA_KEYS)
    require(
        not not_arena,
        "arena overrides",
        not_arena,
        f"fields of tavc_env.ArenaConfig and the shorthands speeds, values: {sorted(ARENA_KEYS)} "
        "(env options go in tavc_env.EnvOptions)",
    )
    if isinstance(spec, Scenario):
        require(
            not overrides,
            f"scenario {spec.name!r} with arena overrides",
            sorted(overrides),
            "a scenario alone (it fixes its arena; build a tavc_env.Scenario of your own to "
            "change it)",
        )
        return Arena(spec.config(), spec, (("scenario", _named_scenario(spec)),))
    if isinstance(spec, ArenaConfig):
        named = (("config", spec), *overrides.items())
        return Arena(make_config(None, spec, **overrides), None, named)
    first: tuple[tuple[str, Any], ...] = () if spec is None else (("preset", spec),)
    return Arena(make_config(spec, **overrides), None, (*first, *overrides.items()))


def _as_scenario(value: object) -> Scenario | None:
    """The scenario `value` is or names (a name or a registry id), or None."""
    if isinstance(value, Scenario):
        return value
    if not isinstance(value, str):
        return None
    if value in SCENARIOS:
        return SCENARIOS[value]
    found = _ID.fullmatch(value)
    if found is not None and found["name"] in SCENARIOS:
        chosen = SCENARIOS[found["name"]]
        if chosen.version == int(found["version"]):
            return chosen
    return None


def resolve_env_kwargs(kwargs: Mapping[str, Any]) -> tuple[Arena, dict[str, Any]]:
    """A plain mapping of env arguments (a choice of `CHOICES`, arena overrides and env options,
    mixed, as a `TrialSpec.env_kwargs`, a BenchMARL task or an RLlib config holds them) as the
    arena and the env-option keyword arguments of `Arena.parallel_env` (`options`, an
    `EnvOptions`, and option fields that change it), checked."""
    rest = dict(kwargs)
    given = rest.pop("options", None)
    require(
        given is None or isinstance(given, EnvOptions), "options", given, "a tavc_env.EnvOptions"
    )
    choice = {k: rest.pop(k) for k in CHOICES if k in rest}
    arena_overrides, changes = split_env_kwargs(rest)
    arena = resolve_arena({**choice, **arena_overrides})
    (given or EnvOptions()).replace(**changes).check(arena.config)  # named before any env is built
    return arena, ({"options": given} if given is not None else {}) | changes


def make_env(**kwargs: Any) -> ArenaEnv[Any]:
    """The env a plain mapping of env arguments describes (`resolve_env_kwargs`): a scenario's,
    or `tavc_env.parallel_env`'s (a preset or config, arena overrides, env options)."""
    arena, options = resolve_env_kwargs(kwargs)
    return arena.parallel_env(**options)
