"""Allocators by name, so a trial can be described by plain data (and rebuilt in a worker process).

Per-robot allocators (`POLICIES`) make one independent policy per robot; team allocators (`TEAMS`)
make one `tavc_agents.policy.Team` per trial, which coordinates its robots. Parameters are keyword
arguments in the trial description, e.g. `("softmax_tavc", {"temperature": 0.01, "init": "paper"})`
or `("greedy", {"model": model.to_dict()})`.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from tavc_agents.allocators.baselines import FixedAllocator, RandomAllocator, StayAllocator
from tavc_agents.allocators.market import AuctionAllocator
from tavc_agents.allocators.teams import GreedyAllocator, StaticAllocator
from tavc_agents.allocators.threshold import ResponseThresholdAllocator
from tavc_agents.learners.network import NetworkTeam
from tavc_agents.learners.tavc import epsilon_tavc, softmax_tavc
from tavc_agents.policy import Policy, Team

POLICIES: Mapping[str, Callable[..., Policy]] = {
    "softmax_tavc": softmax_tavc,
    "epsilon_tavc": epsilon_tavc,
    "random": RandomAllocator,
    "fixed": FixedAllocator,
    "stay": StayAllocator,
}

TEAMS: Mapping[str, Callable[..., Team]] = {
    "static": StaticAllocator,
    "greedy": GreedyAllocator,
    "auction": AuctionAllocator,
    "response_threshold": ResponseThresholdAllocator,
    "network": NetworkTeam,
}

ALLOCATORS = sorted({*POLICIES, *TEAMS})
T = TypeVar("T")


def _build(factory: Callable[..., T], name: str, params: Mapping[str, Any]) -> T:
    """Call `factory(**params)`; parameters it does not take, or required ones that are missing,
    become a ValueError naming only those and, in words, what the allocator takes."""
    signature = inspect.signature(factory)
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
        raise ValueError(
            f"allocator {name!r} needs the parameter{'s' if len(missing) > 1 else ''} "
            f"{', '.join(missing)}; {allowed}"
        )
    return factory(**params)


def make_policy(name: str, **params: Any) -> Policy:
    """A fresh policy of the named per-robot allocator."""
    if name not in POLICIES:
        hint = " (a team allocator: use make_allocator)" if name in TEAMS else ""
        raise ValueError(
            f"allocator {name!r} is not a per-robot policy{hint}; allowed: {sorted(POLICIES)}"
        )
    return _build(POLICIES[name], name, params)


def make_allocator(name: str, **params: Any) -> Callable[[str], Policy] | Team:
    """What `tavc_agents.experiments.runner.run_trial` takes for the named allocator: a `Team`, or a factory
    making a fresh per-robot policy for each agent."""
    if name in TEAMS:
        return _build(TEAMS[name], name, params)
    if name not in POLICIES:
        raise ValueError(f"allocator {name!r} is unknown; allowed: {ALLOCATORS}")
    make_policy(name, **params)  # bad parameters fail here, before the trial starts
    return lambda agent: make_policy(name, **params)
