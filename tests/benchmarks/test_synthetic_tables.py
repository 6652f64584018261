"""Synthetic tables of a chosen elasticity: e comes out as asked, the knee holds, the family is
monotone, the tables are the twin's, and what the family cannot reach is refused."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import tavc_env
from arena_analysis import (
    ALONE,
    CROWDED,
    KNEE_MIN,
    Family,
    Tables,
    elasticity_of,
    max_handling_s,
    reach,
    with_elasticity,
)


def test_pure_multiplicative_crowding_has_unit_elasticity() -> None:
    plain = Family()
    assert plain.elasticity() == pytest.approx(1.0, abs=1e-12)
    assert with_elasticity(1.0) == plain
    # three robots share a circuit freely, the fourth stretches every task by half its free time
    assert [plain.k(n) for n in range(1, 7)] == [1.0, 1.0, 1.0, 1.5, 2.0, 2.5]
    assert plain.mean_s("fast", 1, 0) == 60.0 and plain.mean_s("slow", 2, 3) == 90.0 * 2.0


@pytest.mark.parametrize(
    ("e", "above"),
    [
        (0.75, "pace"),
        (0.9, "pace"),
        (0.99, "pace"),
        (1.01, "pace"),
        (1.4, "pace"),
        (2.0, "pace"),
        (1.1, "wait"),
        (1.17, "wait"),
    ],
)
def test_the_solver_gives_the_elasticity_asked_for(e: float, above: str) -> None:
    family = with_elasticity(e, above="wait" if above == "wait" else "pace")
    assert family.elasticity() == pytest.approx(e, abs=1e-9)
    assert family.knee() >= KNEE_MIN - 1e-12
    moved = {"handling_s": family.handling_s, "pace": family.pace, "wait_s": family.wait_s}
    expected = "handling_s" if e < 1 else "pace" if above == "pace" else "wait_s"
    assert [k for k, v in moved.items() if v > 0] == [expected]  # one mechanism at a time


def test_the_tables_carry_the_family_and_measure_its_elasticity() -> None:
    family = with_elasticity(0.85)
    config = tavc_env.make_config("dahl2004")
    tables = family.tables(config)
    assert tables.switch_cost == 1.13 and tables.n_circuits == 2
    cell = tables.cell(1, (2, 3), "slow")
    assert cell.mean_s == pytest.approx(family.mean_s("slow", 2, 3))
    assert cell.sd_s == pytest.approx(0.1 * cell.mean_s)
    # e read back from the twin's own cells of circuit 0, through the public cell lookup
    cells = (ALONE["fast"], ALONE["slow"], *CROWDED)
    read = Tables(
        fast={(f, s): tables.cell(0, (f, s), "fast").mean_s for f, s in cells if f},
        slow={(f, s): tables.cell(0, (f, s), "slow").mean_s for f, s in cells if s},
    )
    assert elasticity_of(read) == pytest.approx(0.85, abs=1e-9)
    assert "e = 0.8500" in tables.source


def test_the_knee_holds_over_the_reach_and_bounds_it() -> None:
    low, high = reach()
    assert low == pytest.approx(0.744, abs=1e-3) and high == pytest.approx(2.037, abs=1e-3)
    assert reach(above="wait")[1] == pytest.approx(1.174, abs=1e-3)
    edge = dataclasses.replace(Family(), handling_s=max_handling_s(Family()))
    assert edge.knee() == pytest.approx(KNEE_MIN)
    assert dataclasses.replace(edge, handling_s=edge.handling_s * 1.01).knee() < KNEE_MIN
    for e in np.linspace(low, high, 9):
        assert with_elasticity(float(e)).knee() >= KNEE_MIN - 1e-12


def test_the_family_is_monotone() -> None:
    def e_of(**change: float) -> float:
        return dataclasses.replace(Family(), **change).elasticity()

    h = np.linspace(0.0, max_handling_s(Family()), 12)
    assert np.all(np.diff([e_of(handling_s=float(x)) for x in h]) < 0)  # H lowers e
    p = np.linspace(0.0, 1.0, 12)
    assert np.all(np.diff([e_of(pace=float(x)) for x in p]) > 0)  # the pace raises it
    w = np.linspace(0.0, with_elasticity(1.17, above="wait").wait_s, 12)
    assert np.all(np.diff([e_of(wait_s=float(x)) for x in w]) > 0)  # the wait raises it
    # every class's task time grows with either class's robots on the circuit
    family = Family(handling_s=20.0, wait_s=10.0, pace=0.5)
    for cls in ("fast", "slow"):
        grid = np.array(
            [
                [
                    family.mean_s(cls, f, s) if (f if cls == "fast" else s) else np.nan
                    for s in range(4)
                ]
                for f in range(4)
            ]
        )
        assert np.all(np.nan_to_num(np.diff(grid, axis=0), nan=0.0) >= 0)
        assert np.all(np.nan_to_num(np.diff(grid, axis=1), nan=0.0) >= 0)


@pytest.mark.parametrize(("e", "above"), [(0.7, "pace"), (2.1, "pace"), (1.3, "wait")])
def test_an_unreachable_elasticity_is_refused(e: float, above: str) -> None:
    with pytest.raises(ValueError, match=rf"^e = {e} is invalid; allowed: an elasticity in \["):
        with_elasticity(e, above="wait" if above == "wait" else "pace")


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^pace = 1.5 is invalid"):
        Family(pace=1.5)
    with pytest.raises(ValueError, match=r"^b_fast_s = 90.0 is invalid"):
        Family(b_fast_s=90.0)
    with pytest.raises(ValueError, match=r"^handling_s = -1.0 is invalid"):
        Family(handling_s=-1.0)
    with pytest.raises(ValueError, match=r"^counts = \(0, 2\) is invalid"):
        Family().mean_s("fast", 0, 2)
    with pytest.raises(ValueError, match=r"^config = "):
        Family().tables(tavc_env.make_config("dahl2004", speeds=[0.3, 0.25, 0.2]))
