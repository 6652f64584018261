"""Shared checks for user-facing arguments: every failure is a ValueError that names what was
wrong, the value given and what is allowed.

Numbers are coerced here, at one point: `real` and `integer` check a value and return it as a
plain `float` or `int`, so nothing past validation sees a numpy scalar, a `Fraction` or a
`Decimal` (numba, numpy's float16 and string formatting fail on those deep inside a run).

Public: the agent library (`tavc_agents`) and researchers' own code check their arguments with the
same helpers (`require`, `is_number`, `is_integer`, `real`, `integer`), so every refusal of the
project reads alike.
"""

from __future__ import annotations

import decimal
import fractions
import math
import numbers
from collections.abc import Callable, Mapping, Sequence


def is_number(value: object) -> bool:
    """A finite real number (bool excluded: True is not a duration or a speed)."""
    if type(value) is bool:
        return False
    try:
        return isinstance(value, numbers.Real) and math.isfinite(float(value))
    except OverflowError:  # an int or Fraction beyond the floats
        return False


def is_integer(value: object) -> bool:
    """An integer (numpy integers included, bool excluded)."""
    return type(value) is not bool and isinstance(value, numbers.Integral)


MAX_SHOWN = 1000  # characters of a value shown in a message (a 10**400 integer is 401)


def shown(value: object) -> str:
    """`repr(value)` for a message: cut in the middle past MAX_SHOWN characters, and never an
    exception (an int of more than 4300 digits has no repr by default)."""
    try:
        text = repr(value)
    except Exception:  # any failing __repr__ must still give the message
        text = f"<{type(value).__name__} without a repr>"
    if len(text) > MAX_SHOWN:
        text = f"{text[: MAX_SHOWN // 2]}...{text[-20:]} ({len(text)} characters)"
    return text


def require(condition: bool, name: str, value: object, allowed: str) -> None:
    """Raise `ValueError("<name> = <value> is invalid; allowed: <allowed>")` unless `condition`."""
    if not condition:
        raise ValueError(f"{name} = {shown(value)} is invalid; allowed: {allowed}")


def require_together(condition: bool, fields: Mapping[str, object], allowed: str) -> None:
    """A rule relating several fields: its message names every one of them with its value
    ("a, b = 1, 2 is invalid; allowed: ..."), so a consequence is never blamed on one field."""
    if not condition:
        names = ", ".join(fields)
        values = ", ".join(shown(v) for v in fields.values())
        raise ValueError(f"{names} = {values} is invalid; allowed: {allowed}")


def plain_number(value: object) -> float | int | None:
    """`value` as a plain `int` (any integer type but bool) or `float` (any real type a float
    holds exactly: numpy floats of every width, `Fraction(1, 4)`, `Decimal('0.5')`); None if it
    is not a number, is not finite, or a float does not hold it exactly."""
    if isinstance(value, (bool, str, bytes, bytearray)):
        return None
    if isinstance(value, numbers.Integral):
        whole = int(value)
        try:
            return whole if float(whole) == whole else None
        except OverflowError:
            return None
    if isinstance(value, float):  # float and its subclasses (numpy.float64): exact already
        return float(value) if math.isfinite(value) else None
    if not isinstance(value, (numbers.Real, decimal.Decimal)):
        return None
    try:
        as_float = float(value)
    except (OverflowError, ValueError):
        return None
    if not math.isfinite(as_float):
        return None
    return as_float if _exactly(value, as_float) else None


def _exactly(value: numbers.Real | decimal.Decimal, as_float: float) -> bool:
    """Whether `as_float` is exactly `value` (compared as fractions, not rounded)."""
    ratio: Callable[[], tuple[int, int]] | None = getattr(value, "as_integer_ratio", None)
    if ratio is None:
        return bool(value == as_float)
    try:
        return fractions.Fraction(*ratio()) == fractions.Fraction(as_float)
    except (ValueError, OverflowError, TypeError):
        return False


def _hint(value: object) -> str:
    """What to give instead of a number a float does not hold exactly (empty if none)."""
    try:
        near = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        return ""
    if not math.isfinite(near) or isinstance(value, (bool, str, bytes, bytearray)):
        return ""
    if not isinstance(value, (numbers.Real, decimal.Decimal)):
        return ""
    return f" (a float does not hold it exactly: give {near!r})"


def real(
    value: object,
    name: str,
    allowed: str = "a finite number",
    ok: Callable[[float], bool] | None = None,
) -> float | int:
    """`value` as a plain `float` (or `int`, if it is an integer: an integer field of a record
    keeps its repr, which digests of saved trials hash) after checking it is a finite real
    number for which `ok` holds; otherwise a ValueError naming `name`, the value and `allowed`."""
    number = plain_number(value)
    if number is None:
        raise ValueError(f"{name} = {shown(value)} is invalid; allowed: {allowed}{_hint(value)}")
    require(ok is None or ok(number), name, value, allowed)
    return number


def integer(
    value: object,
    name: str,
    allowed: str = "an integer",
    ok: Callable[[int], bool] | None = None,
) -> int:
    """`value` as a plain `int` (any integer type; not bool, not a float, even a whole one) for
    which `ok` holds; otherwise a ValueError naming `name`, the value and `allowed`."""
    require(is_integer(value), name, value, allowed)
    assert isinstance(value, numbers.Integral)
    whole = int(value)
    require(ok is None or ok(whole), name, value, allowed)
    return whole


def point(value: object, name: str, allowed: str) -> tuple[float, float]:
    """`value` as a pair of plain floats: a sequence of two finite numbers (not a string or
    bytes, whose items would pass for numbers); otherwise a ValueError naming `name`."""
    ok = (
        isinstance(value, Sequence)
        and not isinstance(value, (str, bytes, bytearray))
        and len(value) == 2
    )
    require(ok, name, value, allowed)
    assert isinstance(value, Sequence)
    for item in value:
        if plain_number(item) is None:
            raise ValueError(f"{name} = {shown(value)} is invalid; allowed: {allowed}{_hint(item)}")
    return (float(value[0]), float(value[1]))
