"""Hypothesis profiles of the fuzzing harness, chosen by the environment variable TAVC_FUZZ.

* unset or `ci`: the default, part of `python -m pytest`: derandomized (the same examples every
  run, so the suite is reproducible), no example database; each test's own example count.
* `long`: `TAVC_FUZZ=long python -m pytest tests/fuzz -n 2 -q`: 25 times the examples, random,
  with failing examples kept in .hypothesis/tavc-fuzz and replayed first on the next run.

Tests take their settings from `tests.fuzz.strategies.fuzz_settings(examples)`.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings
from hypothesis.database import DirectoryBasedExampleDatabase

PROFILES = ("ci", "long")
LONG_FACTOR = 25

_slow = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much]
settings.register_profile(
    "tavc-fuzz-ci",
    deadline=None,
    derandomize=True,
    database=None,
    print_blob=True,
    suppress_health_check=_slow,
)
settings.register_profile(
    "tavc-fuzz-long",
    deadline=None,
    database=DirectoryBasedExampleDatabase(".hypothesis/tavc-fuzz"),
    print_blob=True,
    suppress_health_check=_slow,
)


def pytest_configure(config: pytest.Config) -> None:
    profile = os.environ.get("TAVC_FUZZ", "ci") or "ci"
    if profile not in PROFILES:
        raise pytest.UsageError(f"TAVC_FUZZ = {profile!r} is invalid; allowed: {list(PROFILES)}")
