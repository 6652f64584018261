"""The fixed-allocation runs that measure elasticity (`tavc_agents.analysis.elasticity`) in any arena.

Elasticity compares what crowding costs a fast (0.30 m/s) and a slow (0.20 m/s) robot: T_c(f, s) is
the mean task time of a robot of class c when f fast and s slow robots serve circuit 0. The runs
are those of the interference study's cross-interference (`tavc_agents.studies.interference`), made for
any `ArenaConfig`: its arena (geometry, stations, physics) with the team replaced by
`PER_CLASS` fast robots (0-2) and `PER_CLASS` slow ones (3-5), scheduled breakdowns removed.
With two or more circuits, f fast and s slow robots serve circuit 0 and the rest circuit 1, as in
the study (for the dahl2004 presets the runs are the study's own); an arena of one circuit holds
only the f + s robots.

    alloc = cross_allocation(tavc_env.preset("dahl2004"), 2, 1, seed=0, hours=3.0,
                             warmup_s=600.0, skip_first=2)
    run_fixed(alloc)  # tavc_env.measurement
"""

from __future__ import annotations

from typing import Any

from tavc_env.config import ArenaConfig, Robot, preset_overrides
from tavc_env.measurement import FixedAllocation, two_circuit_allocation

FAST = Robot(0.30, "fast")
SLOW = Robot(0.20, "slow")
PER_CLASS = 3
"""robots of each class in a run (with two or more circuits)"""
BASE_PRESET = "dahl2004"
"""the preset a run's arena is given relative to (`FixedAllocation.arena`)"""

Cell = tuple[int, int]
"""(fast, slow robots on circuit 0)"""
ALONE: dict[str, Cell] = {"fast": (1, 0), "slow": (0, 1)}
"""the cell in which a robot of the class is alone on circuit 0"""
CROWDED: tuple[Cell, ...] = tuple(
    (f, s) for f in range(1, PER_CLASS + 1) for s in range(1, PER_CLASS + 1)
)
"""the cells with both classes on circuit 0 (f, s in 1..3), over which elasticity averages"""
CELLS: tuple[Cell, ...] = (ALONE["fast"], ALONE["slow"], *CROWDED)
"""the runs elasticity needs (11 of the 16 cells f, s in 0..3)"""


def _check_cell(fast: int, slow: int) -> None:
    for name, n in (("fast", fast), ("slow", slow)):
        ok = isinstance(n, int) and not isinstance(n, bool) and 0 <= n <= PER_CLASS
        if not ok:
            raise ValueError(f"{name} = {n!r} is invalid; allowed: an integer in 0..{PER_CLASS}")
    if fast + slow == 0:
        raise ValueError("fast = slow = 0 is invalid; allowed: at least one robot on circuit 0")


def cross_circuits(fast: int, slow: int, n_circuits: int) -> tuple[int, ...]:
    """Each robot's circuit in the run of cell (fast, slow): with two or more circuits, fast robots
    0..fast-1 and slow robots 3..3+slow-1 on circuit 0, the others on circuit 1; with one circuit
    the fast + slow robots, all on it."""
    _check_cell(fast, slow)
    if n_circuits >= 2:
        return two_circuit_allocation(fast, PER_CLASS) + two_circuit_allocation(slow, PER_CLASS)
    return (0,) * (fast + slow)


def cross_arena(config: ArenaConfig, fast: int, slow: int) -> ArenaConfig:
    """`config`'s arena with the team of the run of cell (fast, slow) (see `cross_circuits`) and no
    scheduled breakdowns."""
    if not isinstance(config, ArenaConfig):
        raise ValueError(f"config = {config!r} is invalid; allowed: a tavc_env.ArenaConfig")
    _check_cell(fast, slow)
    if config.n_circuits >= 2:
        robots = (FAST,) * PER_CLASS + (SLOW,) * PER_CLASS
    else:
        robots = (FAST,) * fast + (SLOW,) * slow
    return config.replace(robots=robots, breakdowns=())


def arena_overrides(config: ArenaConfig, preset: str = BASE_PRESET) -> tuple[tuple[str, Any], ...]:
    """The fields in which `config` differs from `preset` (`tavc_env.config.preset_overrides`,
    from the study's base preset by default)."""
    return preset_overrides(config, preset)


def cross_allocation(
    config: ArenaConfig,
    fast: int,
    slow: int,
    *,
    seed: int,
    hours: float,
    warmup_s: float,
    skip_first: int,
) -> FixedAllocation:
    """The fixed-allocation run of cell (fast, slow) in `config`'s arena (see the module)."""
    arena = cross_arena(config, fast, slow)
    return FixedAllocation(
        preset=BASE_PRESET,
        circuit_of=cross_circuits(fast, slow, arena.n_circuits),
        seed=seed,
        hours=hours,
        warmup_s=warmup_s,
        skip_first=skip_first,
        arena=arena_overrides(arena),
    )
