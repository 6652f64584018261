"""`scaled_config` (issue 24): the arena it builds is the first candidate (lane spacing, then
height) that the full validation accepts, found without validating every candidate in full; sizes
it cannot build are refused at once, naming the largest it can."""

from __future__ import annotations

import pytest

import tavc_env
from tavc_env import config as config_module
from tavc_env.config import MAX_SCALED_ROBOTS, ArenaConfig, lane_circuits


def first_valid_by_full_validation(n_circuits: int, per_circuit: int) -> ArenaConfig:
    """The search as it was: every candidate validated in full, in order."""
    n = n_circuits * per_circuit
    robots = tavc_env.robots_from_speeds([(0.30, 0.20)[i % 2] for i in range(n)])
    values = [2200.0 - 10.0 * i for i in range(n_circuits)]
    for spacing in (9.0 * f for f in (1.0, 1.5, 2.0, 3.0, 4.0)):
        width = 3.0 + spacing * max(n_circuits - 1, 1)
        for height in range(8, 82, 2):
            try:
                return ArenaConfig(
                    width=width,
                    height=float(height),
                    circuits=lane_circuits(n_circuits, width, float(height), values),
                    robots=robots,
                )
            except ValueError as error:
                if "waiting line" not in str(error):
                    raise
    raise AssertionError("no arena")


@pytest.mark.parametrize(("lanes", "per"), [(1, 1), (2, 3), (3, 8), (8, 3), (4, 12), (1, 30)])
def test_the_arena_is_the_one_full_validation_picks(lanes: int, per: int) -> None:
    assert tavc_env.scaled_config(lanes, per) == first_valid_by_full_validation(lanes, per)


def test_the_96_robot_arena() -> None:
    config = tavc_env.scaled_config(32, 3)
    assert (config.width, config.height, config.n_robots) == (282.0, 48.0, 96)


def test_too_many_robots_are_refused_at_once() -> None:
    with pytest.raises(ValueError, match=f"allowed: at most {MAX_SCALED_ROBOTS} robots"):
        tavc_env.scaled_config(200, 3)


def test_lines_that_cannot_hold_the_team_name_the_largest_team(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # (under the cap the floor's room runs out first; above it the lines do)
    monkeypatch.setattr(config_module, "MAX_SCALED_ROBOTS", 900)
    with pytest.raises(ValueError, match=r"allowed: at most 29 robots per circuit with 30 circ"):
        tavc_env.scaled_config(30, 30)
    with pytest.raises(ValueError, match=r"robots cannot fit"):  # the floor, before the lines
        tavc_env.scaled_config(2, 100)
