"""Allocators by name, so a trial can be described by plain data (and rebuilt in a worker process).

Each entry makes the policy for one agent. Parameters are given as keyword arguments in the trial
description, e.g. `("softmax_tavc", {"temperature": 0.01, "init": "paper"})`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from agents.baselines import RandomAllocator
from agents.policy import Policy
from agents.tavc import epsilon_tavc, softmax_tavc

ALLOCATORS: Mapping[str, Callable[..., Policy]] = {
    "softmax_tavc": softmax_tavc,
    "epsilon_tavc": epsilon_tavc,
    "random": RandomAllocator,
}


def make_policy(name: str, **params: Any) -> Policy:
    """A fresh policy of the named allocator."""
    if name not in ALLOCATORS:
        raise ValueError(f"allocator {name!r} is unknown; allowed: {sorted(ALLOCATORS)}")
    return ALLOCATORS[name](**params)
