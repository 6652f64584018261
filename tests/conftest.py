"""Fixtures for the tavc-env test suite; plain helpers live in tests/helpers.py.

Rendering runs headless: SDL's dummy video driver is selected here, before anything imports pygame.
"""

from __future__ import annotations

import os

os.environ["SDL_VIDEODRIVER"] = "dummy"
os.environ["SDL_AUDIODRIVER"] = "dummy"
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

from collections.abc import Iterator
from typing import Any

import pytest

from tests.helpers import CrowdTrace, figure_problems, record_crowd_run


@pytest.fixture(autouse=True, scope="session")
def figures_stand_alone() -> Iterator[None]:
    """Every figure saved in the test process (fixtures of any scope included) is checked as it is
    saved: labelled axes, bar charts that start at zero, a legend where several series are drawn
    (`tests.helpers.figure_problems`)."""
    try:
        import matplotlib.figure
    except ImportError:
        yield
        return
    original = matplotlib.figure.Figure.savefig

    def checked(self: Any, *args: Any, **kwargs: Any) -> None:
        problems = figure_problems(self)
        assert not problems, f"figure saved to {args[0] if args else '?'}: {problems}"
        original(self, *args, **kwargs)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(matplotlib.figure.Figure, "savefig", checked)
        yield


@pytest.fixture(scope="session")
def crowd_trace() -> CrowdTrace:
    """One 30-simulated-minute run of all six `dahl2004` robots crowding circuit 0, recorded every
    physics tick (about 5 s of wall time; computed once per test process)."""
    return record_crowd_run(seed=0)


def pytest_configure(config: pytest.Config) -> None:
    # pettingzoo.test imports its example envs through a deprecated shim at collection time; that
    # notice is PettingZoo's own and says nothing about tavc-env.
    config.addinivalue_line(
        "filterwarnings", "ignore:The old environment creation API:DeprecationWarning"
    )
