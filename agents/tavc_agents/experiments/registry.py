"""Allocators by name, so a trial can be described by plain data (and rebuilt in a worker process).

There are two kinds, one registry: a *per-robot* allocator's factory makes one independent
`tavc_agents.policy.Policy` (a learner such as `softmax_tavc`, or a fixed rule such as `random`),
and the trial gets a fresh one for each robot; a *team* allocator's factory makes one
`tavc_agents.policy.Team` per trial, which coordinates its robots. Parameters are keyword
arguments in the trial description, e.g. `("softmax_tavc", {"temperature": 0.01, "init":
"paper"})` or `("greedy", {"model": model.to_dict()})`.

Your own allocator gets a name in either of two ways:

- at run time, `register_allocator("mine", MyPolicy)` (or `team=True` for a `Team` factory): this
  process, and the local sweep's worker processes, which receive the run-time registrations;
- from your own package, an entry point in the group `tavc.allocators` (`mine =
  "my_package.module:MyPolicy"`, or a `team_allocator(MyTeam)` object for a team): every process
  that has the package installed, including Ray workers, finds it by name on first use.

`REGISTRY` is the module-level default registry; the functions below are its methods.
"""

from __future__ import annotations

import inspect
import re
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from importlib import metadata
from typing import Any

from tavc_agents.allocators.baselines import FixedAllocator, RandomAllocator, StayAllocator
from tavc_agents.allocators.market import AuctionAllocator
from tavc_agents.allocators.teams import GreedyAllocator, StaticAllocator
from tavc_agents.allocators.threshold import ResponseThresholdAllocator
from tavc_agents.learners.network import NetworkTeam
from tavc_agents.learners.own_reward import own_reward
from tavc_agents.learners.tavc import epsilon_tavc, softmax_tavc
from tavc_agents.policy import Policy, Team

ENTRY_POINT_GROUP = "tavc.allocators"
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.-]*$")
NAME_RULE = "a letter or _, then letters, digits, _ . or - (no spaces, no '=')"


class PluginError(ValueError):
    """An allocator's entry point could not be loaded, or does not name a factory."""


@dataclass(frozen=True)
class TeamFactory:
    """A factory of `Team`s, marked as such: what an entry point names for a team allocator (an
    entry point cannot pass `team=True`). Calling it calls the factory."""

    factory: Callable[..., Team]

    def __call__(self, **params: Any) -> Team:
        return self.factory(**params)


def team_allocator(factory: Callable[..., Team]) -> TeamFactory:
    """Mark `factory` as making `Team`s, for an entry point: `my_team = team_allocator(MyTeam)`
    in your package, and `mine = "my_package.module:my_team"` in its `tavc.allocators` group."""
    _require_callable(factory, "team_allocator")
    return TeamFactory(factory)


@dataclass(frozen=True)
class Allocator:
    """A named allocator: its factory, its kind and where it came from."""

    name: str
    factory: Callable[..., Any]
    team: bool
    origin: str  # "built in", "registered at run time", or the entry point and its distribution

    @property
    def kind(self) -> str:
        return "team allocator" if self.team else "per-robot policy"


def _require_callable(factory: object, name: str) -> None:
    if not callable(factory):
        raise TypeError(
            f"the factory of allocator {name!r} is {factory!r}, which is not callable; allowed: a "
            "function or class that takes the allocator's parameters as keywords"
        )


class AllocatorRegistry:
    """Allocators by name: the built-in ones, those registered at run time and those of installed
    packages' `tavc.allocators` entry points (loaded when first named, or when all are listed)."""

    def __init__(self, built_in: Iterable[Allocator], group: str | None = ENTRY_POINT_GROUP):
        self._entries = {a.name: a for a in built_in}
        self._built_in = frozenset(self._entries)
        self._runtime: dict[str, Allocator] = {}
        self._group = group
        self._plugins: dict[str, metadata.EntryPoint] | None = None
        self._refused: dict[str, metadata.EntryPoint] = {}  # entry points with invalid names

    # -- naming -------------------------------------------------------------------------------
    def register(
        self,
        name: str,
        factory: Callable[..., Policy] | Callable[..., Team],
        *,
        team: bool = False,
        replace: bool = False,
    ) -> None:
        """Name `factory`: it makes a fresh `Policy` per robot (or, with `team=True` or a
        `team_allocator` factory, one `Team` per trial) from the allocator's parameters as
        keywords. A name already taken (built in, registered or an entry point's) is refused
        unless `replace=True`."""
        if not isinstance(name, str) or not _NAME.match(name):
            raise ValueError(f"allocator name {name!r} is invalid; allowed: {NAME_RULE}")
        _require_callable(factory, name)
        if isinstance(factory, TeamFactory):
            factory, team = factory.factory, True
        if not replace and name in self.names():
            entry = self._entries.get(name)
            taken = entry.origin if entry else _where(self._entry_points()[name])
            raise ValueError(
                f"allocator {name!r} is taken ({taken}); allowed: another name, or "
                "replace=True to replace it"
            )
        made = Allocator(name, factory, bool(team), "registered at run time")
        self._entries[name] = self._runtime[name] = made

    def registered_at_run_time(self) -> tuple[Allocator, ...]:
        """What `register` added in this process (what worker processes must be told)."""
        return tuple(self._runtime.values())

    def names(self, *, team: bool | None = None) -> list[str]:
        """Every allocator's name, sorted (only team allocators with `team=True`, only per-robot
        ones with `team=False`: that loads every entry point, to learn its kind)."""
        names = {*self._entries, *self._entry_points()}
        if team is None:
            return sorted(names)
        return sorted(n for n in names if self._kind_or_none(n) is team)

    def get(self, name: str) -> Allocator:
        """The allocator called `name`; a ValueError naming the known ones otherwise."""
        if name not in self._entries:
            point = self._entry_points().get(name)
            if point is None and name in self._refused:
                raise PluginError(
                    f"allocator {name!r} of the {_where(self._refused[name])} is refused: its "
                    f"name is invalid; allowed: {NAME_RULE}"
                )
            if point is None:
                raise ValueError(f"allocator {name!r} is unknown; allowed: {self.names()}")
            self._entries[name] = _load(point)
        return self._entries[name]

    def _kind_or_none(self, name: str) -> bool | None:
        try:
            return self.get(name).team
        except PluginError as error:
            warnings.warn(str(error), stacklevel=3)
            return None

    def _entry_points(self) -> dict[str, metadata.EntryPoint]:
        if self._plugins is None:
            found: dict[str, metadata.EntryPoint] = {}
            points = metadata.entry_points(group=self._group) if self._group else ()
            for point in points:
                if not _NAME.match(point.name):  # the rule `register` applies
                    self._refused.setdefault(point.name, point)
                    warnings.warn(
                        f"the {_where(point)} is ignored: the name {point.name!r} is invalid; "
                        f"allowed: {NAME_RULE}",
                        stacklevel=2,
                    )
                elif point.name in self._built_in:
                    warnings.warn(
                        f"the {_where(point)} is ignored: {point.name!r} is a built-in allocator",
                        stacklevel=2,
                    )
                else:
                    found.setdefault(point.name, point)  # one name twice: the first on the path
            self._plugins = found
        return self._plugins

    # -- building -----------------------------------------------------------------------------
    def make_policy(self, name: str, **params: Any) -> Policy:
        """A fresh policy of the named per-robot allocator."""
        entry = self.get(name)
        if entry.team:
            raise ValueError(
                f"allocator {name!r} is not a per-robot policy (a team allocator: use "
                f"make_allocator); allowed: {self.names(team=False)}"
            )
        return _checked(entry, _build(entry.factory, name, params))

    def make_allocator(self, name: str, **params: Any) -> Callable[[str], Policy] | Team:
        """What `tavc_agents.experiments.runner.run_trial` takes for the named allocator: a
        `Team`, or a factory making a fresh per-robot policy for each agent."""
        entry = self.get(name)
        if entry.team:
            return _checked(entry, _build(entry.factory, name, params))
        self.make_policy(name, **params)  # bad parameters fail here, before the trial starts
        return lambda agent: self.make_policy(name, **params)


def _where(point: metadata.EntryPoint) -> str:
    """An entry point and the distribution that declares it, for messages."""
    dist = point.dist
    of = f"{dist.name} {dist.version}" if dist is not None else "an installed package"
    return f"entry point {point.name} = {point.value!r} of {of}"


def _load(point: metadata.EntryPoint) -> Allocator:
    """The allocator an entry point names; a `PluginError` naming the plugin if it cannot load."""
    where = _where(point)
    try:
        factory = point.load()
    except KeyboardInterrupt:
        raise
    except SystemExit as error:  # its import must not end the program, silently
        raise PluginError(
            f"allocator {point.name!r} could not be loaded from the {where}: importing it called "
            f"sys.exit({error.code!r}); allowed: a module that imports without exiting"
        ) from None
    except BaseException as error:  # whatever the plugin's import raises is the plugin's fault
        raise PluginError(
            f"allocator {point.name!r} could not be loaded from the {where}: "
            f"{type(error).__name__}: {error}"
        ) from error
    if not callable(factory):
        raise PluginError(
            f"allocator {point.name!r}: the {where} names {factory!r}, which is not callable; "
            "allowed: a policy factory, or team_allocator(factory) for a team"
        )
    if isinstance(factory, TeamFactory):
        return Allocator(point.name, factory.factory, True, where)
    return Allocator(point.name, factory, False, where)


def _checked(entry: Allocator, made: Any) -> Any:
    """`made`, if it is what `entry`'s kind promises; a ValueError saying what it is otherwise."""
    expected = Team if entry.team else Policy
    if not isinstance(made, expected):
        other = " (it is a Team: register it with team=True)" if isinstance(made, Team) else ""
        raise ValueError(
            f"allocator {entry.name!r} ({entry.origin}) is a {entry.kind}, but its factory made "
            f"{type(made).__name__!r}{other}; allowed: an object with "
            + ("policies() and observe()" if entry.team else "reset(), act() and update()")
        )
    return made


def _build(factory: Callable[..., Any], name: str, params: Mapping[str, Any]) -> Any:
    """Call `factory(**params)`; parameters it does not take, or required ones that are missing,
    become a ValueError naming only those and, in words, what the allocator takes."""
    signature = inspect.signature(factory)
    if any(p.kind is p.VAR_KEYWORD for p in signature.parameters.values()):
        return factory(**params)  # takes any keyword: it names what it refuses itself
    takes = {
        p.name: p
        for p in signature.parameters.values()
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    }
    described = ", ".join(
        p.name if p.default is p.empty else f"{p.name} (default {p.default!r})"
        for p in takes.values()
    )
    allowed = f"allowed: {described}" if takes else "allowed: no parameters"
    unknown = sorted(set(params) - set(takes))
    if unknown:
        raise ValueError(
            f"allocator {name!r} has no parameter{'s' if len(unknown) > 1 else ''} "
            f"{', '.join(unknown)}; {allowed}"
        )
    missing = [n for n, p in takes.items() if p.default is p.empty and n not in params]
    if missing:
        # the factory's own description says what a missing value is (a path, a model ...)
        about = (inspect.getdoc(factory) or "").split("\n\n")[0].replace("\n", " ")
        raise ValueError(
            f"allocator {name!r} needs the parameter{'s' if len(missing) > 1 else ''} "
            f"{', '.join(missing)}; {allowed}" + (f" ({about})" if about else "")
        )
    return factory(**params)


_POLICIES: dict[str, Callable[..., Policy]] = {
    "softmax_tavc": softmax_tavc,
    "epsilon_tavc": epsilon_tavc,
    "own_reward": own_reward,
    "random": RandomAllocator,
    "fixed": FixedAllocator,
    "stay": StayAllocator,
}
_TEAMS: dict[str, Callable[..., Team]] = {
    "static": StaticAllocator,
    "greedy": GreedyAllocator,
    "auction": AuctionAllocator,
    "response_threshold": ResponseThresholdAllocator,
    "network": NetworkTeam,
}
BUILT_IN = tuple(
    Allocator(name, factory, team, "built in")
    for team, table in ((False, _POLICIES), (True, _TEAMS))
    for name, factory in table.items()
)

REGISTRY = AllocatorRegistry(BUILT_IN)
"""The registry that `run_trial`'s callers, sweeps, studies and `tavc trial` use by name; its
state is the only module-level state of the package that a user changes (`register_allocator`)."""
register_allocator = REGISTRY.register
make_policy = REGISTRY.make_policy
make_allocator = REGISTRY.make_allocator
allocator_names = REGISTRY.names
