"""Shared checks for user-facing arguments: every failure is a ValueError that names what was
wrong, the value given and what is allowed."""

from __future__ import annotations

import math
import numbers


def is_number(value: object) -> bool:
    """A finite real number (bool excluded: True is not a duration or a speed)."""
    if type(value) is bool:
        return False
    return isinstance(value, numbers.Real) and math.isfinite(float(value))


def is_integer(value: object) -> bool:
    """An integer (numpy integers included, bool excluded)."""
    return type(value) is not bool and isinstance(value, numbers.Integral)


def require(condition: bool, name: str, value: object, allowed: str) -> None:
    """Raise `ValueError("<name> = <value> is invalid; allowed: <allowed>")` unless `condition`."""
    if not condition:
        raise ValueError(f"{name} = {value!r} is invalid; allowed: {allowed}")
