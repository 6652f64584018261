"""The ranges a command line's seeds and simulated hours must be in, and whether the Ray backend
can run: checked where a command line is read (`tavc trial`, `tavc plot`, and every study's
settings, `StudySettings`), so that a value out of range is refused in one line before any work,
not deep inside a trial (a seed of -1 in numpy's seeding, 1e308 hours in the progress bar)."""

from __future__ import annotations

import dataclasses
import importlib.util
import math

from tavc_env.validation import is_integer, is_number

MAX_SEED = 2**63 - 1
"""The largest seed: a signed 64-bit integer, what every library a trial may hand a seed to holds."""
SEEDS = "an integer in [0, 2**63 - 1]"
MAX_HOURS = 100_000.0
"""The longest simulated period a command line takes, in hours (about 11 simulated years; the
longest study runs 20): longer is a typo, and `inf` or 1e308 hours would overflow the clock."""


def valid_seed(value: object) -> bool:
    """An integer (not a bool) in [0, MAX_SEED]."""
    return is_integer(value) and 0 <= int(value) <= MAX_SEED  # type: ignore[call-overload]


def valid_hours(value: object, *, zero: bool) -> bool:
    """A finite number of simulated hours in (0, MAX_HOURS], or [0, MAX_HOURS] if `zero`."""
    if not is_number(value):
        return False
    hours = float(value)  # type: ignore[arg-type]
    return (hours >= 0 if zero else hours > 0) and hours <= MAX_HOURS and math.isfinite(hours)


def hours_allowed(*, zero: bool) -> str:
    """What `valid_hours` allows, for a message."""
    return f"a finite number {'>= 0' if zero else '> 0'} and <= {MAX_HOURS:g} (simulated hours)"


def ray_installed() -> bool:
    """Whether Ray can be imported (found without importing it: that takes seconds)."""
    return importlib.util.find_spec("ray") is not None


RAY_MISSING = (
    "Ray is not installed (pip install 'tavc-env[ray]'); allowed: 'local', or install Ray first"
)


def check_settings(settings: object) -> None:
    """Refuse (ValueError naming the field) a study setting out of range: a seed (`seed`, `seed0`,
    `*_seed`; not `seeds`, a count) outside [0, 2**63 - 1], simulated hours (`hours`, `*_hours`,
    `*_h`) not finite or outside [0, MAX_HOURS] (a study refuses 0 where it needs more), and
    `backend = 'ray'` without Ray. None (a default decided later) is not checked here."""
    assert dataclasses.is_dataclass(settings)
    for field in dataclasses.fields(settings):
        name, value = field.name, getattr(settings, field.name)
        if value is None:  # a setting left to its default (e.g. a scenario's own episode)
            continue
        if name in ("seed", "seed0") or name.endswith("_seed"):
            if not valid_seed(value):
                raise ValueError(f"{name} = {value!r} is invalid; allowed: {SEEDS}")
        elif name == "hours" or name.endswith(("_hours", "_h")):
            if not valid_hours(value, zero=True):
                raise ValueError(
                    f"{name} = {value!r} is invalid; allowed: a finite number of simulated "
                    f"hours, not negative, at most {MAX_HOURS:g}"
                )
        elif name == "backend" and value == "ray" and not ray_installed():
            raise ValueError(f"backend = 'ray' is invalid: {RAY_MISSING}")
