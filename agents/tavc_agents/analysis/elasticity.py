"""Elasticity of the arena: how crowding's cost splits between fast and slow robots.

With fixed allocations, T_c(f, s) is the mean task time of a robot of class c (fast 0.30 m/s, slow
0.20 m/s) when f fast and s slow robots serve the same circuit (circuit 0 of the interference
study's "cross" runs; `cross_allocation` below makes them for any arena). Then

    e = mean_{f,s in 1..3} ln(T_fast(f, s) / T_fast(1, 0))
        / mean_{f,s in 1..3} ln(T_slow(f, s) / T_slow(0, 1))

e = 1: crowding costs every robot the same fraction of its time (pure multiplicative crowding);
e > 1: fast robots lose more (an additive wait is a larger share of a shorter task); e < 1: slow
robots lose more. The means run over the nine cells where both classes share the circuit; each
class is compared with itself alone on it.

Beside e, the pace in company

    rho = T_slow(1, 1) / T_fast(1, 1)

says whether a fast robot keeps its speed advantage when it shares the circuit with one slow robot:
rho = 1 means it is held to the slow robot's pace (behind it at a one-robot dock, or braking
behind it on a leg it cannot pass on), and rho = T_slow(0, 1) / T_fast(1, 0), the ratio alone, is
its ceiling. Its interval is the same seed bootstrap, drawn after e's.

Over seeds: the point estimate is e of the tables averaged cell by cell over seeds; its interval
is a percentile bootstrap that resamples whole seeds (each seed's runs together) and recomputes
that estimate (`scipy.stats.bootstrap`, method "percentile"). With few seeds the bootstrap cannot
see beyond the observed spread and its interval is too narrow. Everything here is a pure
function of its arguments (the random draws come from the Generator passed in).

The runs: each cell's run is the interference study's cross-interference run, made for any
`ArenaConfig`: its arena (geometry, stations, physics) with the team replaced by `PER_CLASS` fast
robots (0-2) and `PER_CLASS` slow ones (3-5), scheduled breakdowns removed. With two or more
circuits, f fast and s slow robots serve circuit 0 and the rest circuit 1, as in the study (for
the dahl2004 presets the runs are the study's own); an arena of one circuit holds only the f + s
robots.

    alloc = cross_allocation(tavc_env.preset("dahl2004"), 2, 1, seed=0, hours=3.0,
                             warmup_s=600.0, skip_first=2)
    run_fixed(alloc)  # tavc_env.measurement
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from scipy import stats

from tavc_agents.analysis.interference import cross_cell
from tavc_env.config import ArenaConfig, Robot, preset_overrides
from tavc_env.measurement import FixedAllocation, two_circuit_allocation

# -- the runs elasticity needs ---------------------------------------------------------------------

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


# -- elasticity from the runs ------------------------------------------------------------------

Row = dict[str, Any]
CLASSES = ("fast", "slow")


class Tables(NamedTuple):
    """T_fast(f, s) and T_slow(f, s), mean task times (s) by (fast, slow robots on the circuit)."""

    fast: Mapping[Cell, float]
    slow: Mapping[Cell, float]


@dataclass(frozen=True)
class Elasticity:
    """e with its percentile-bootstrap interval over seeds, and the two mean log-ratios it is the
    quotient of (both averaged over the cells f, s in 1..3)."""

    e: float
    low: float
    high: float
    n_seeds: int
    fast_mean_log_ratio: float
    """mean ln(T_fast(f, s) / T_fast(1, 0))"""
    slow_mean_log_ratio: float
    """mean ln(T_slow(f, s) / T_slow(0, 1))"""
    confidence: float = 0.95
    rho: float = math.nan
    """pace in company, T_slow(1, 1) / T_fast(1, 1), of the tables averaged over seeds"""
    rho_low: float = math.nan
    rho_high: float = math.nan
    rho_alone: float = math.nan
    """T_slow(0, 1) / T_fast(1, 0): rho's ceiling, the two classes' ratio alone on the circuit"""

    def text(self, digits: int = 3) -> str:
        """The text "e [low, high]" (the interval left out where there is none)."""
        return _with_interval(self.e, self.low, self.high, digits)

    def rho_text(self, digits: int = 3) -> str:
        """The text "rho [low, high]" (the interval left out where there is none)."""
        return _with_interval(self.rho, self.rho_low, self.rho_high, digits)


def _with_interval(value: float, low: float, high: float, digits: int) -> str:
    text = f"{value:.{digits}f}"
    if math.isfinite(low) and math.isfinite(high):
        return f"{text} [{low:.{digits}f}, {high:.{digits}f}]"
    return text


def seed_tables(rows: Sequence[Row], seeds: Iterable[int] | None = None) -> dict[int, Tables]:
    """Per seed, the tables T_fast and T_slow on circuit 0 from the group rows of "cross" runs
    (`tavc_agents.analysis.interference.group_rows`, experiment "cross", labelled f:s): every cell
    f, s in 0..3 in which the class is present and the rows have a value. `seeds`: those to take
    (default: every seed with a cross row). Missing cells are left out (`elasticity` names them)."""
    if seeds is None:
        seeds = sorted({r["seed"] for r in rows if r["experiment"] == "cross"})
        if not seeds:
            raise ValueError("rows has no row of a 'cross' run; allowed: the rows of cross runs")
    wanted = list(seeds)
    found: dict[tuple[int, str], dict[Cell, float]] = {
        (seed, cls): {} for seed in wanted for cls in CLASSES
    }
    for f in range(PER_CLASS + 1):
        for s in range(PER_CLASS + 1):
            for cls in CLASSES:
                if (f if cls == "fast" else s) == 0:
                    continue  # the class is not on the circuit
                sel = cross_cell(rows, f, s, 0, cls)
                for seed in wanted:
                    if seed in sel:
                        found[(seed, cls)][(f, s)] = float(sel[seed]["mean_task_time_s"])
    return {seed: Tables(found[(seed, "fast")], found[(seed, "slow")]) for seed in wanted}


def _cells(cls: str) -> tuple[Cell, ...]:
    return (ALONE[cls], *CROWDED)


def _column(tables: Tables, cls: str, where: str) -> list[float]:
    """The class's times in the cells e uses (alone first), refusing a missing cell or a time that
    is not a finite number > 0."""
    table = tables.fast if cls == "fast" else tables.slow
    values = []
    for cell in _cells(cls):
        if cell not in table:
            raise ValueError(
                f"T_{cls}{cell} is missing{where}; allowed: tables with every cell "
                f"{list(_cells(cls))}"
            )
        v = table[cell]
        ok = isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v > 0
        if not ok:
            raise ValueError(
                f"T_{cls}{cell} = {v!r}{where} is invalid; allowed: a finite task time > 0 s"
            )
        values.append(float(v))
    return values


def log_ratios(tables: Tables) -> tuple[float, float]:
    """The mean over f, s in 1..3 of ln(T_fast(f, s) / T_fast(1, 0)) and of
    ln(T_slow(f, s) / T_slow(0, 1)). A ValueError names a missing cell or a bad time."""
    fast = np.asarray(_column(tables, "fast", ""))
    slow = np.asarray(_column(tables, "slow", ""))
    return _mean_log_ratio(fast), _mean_log_ratio(slow)


def _mean_log_ratio(times: np.ndarray) -> Any:
    """Along the last axis: the cell times, the alone cell first."""
    return np.log(times[..., 1:] / times[..., :1]).mean(axis=-1)


def _quotient(num: Any, den: Any) -> Any:
    """num / den, nan where den is 0 (crowding costs the slow robots nothing: e is undefined)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den != 0, num / np.where(den != 0, den, 1.0), np.nan)


def elasticity_of(tables: Tables) -> float:
    """e of one set of tables (nan if the slow robots' mean log-ratio is 0)."""
    fast, slow = log_ratios(tables)
    return float(_quotient(fast, slow))


def _arrays(per_seed: Mapping[int, Tables] | Sequence[Tables]) -> tuple[np.ndarray, np.ndarray]:
    """(seeds, cells) arrays of the fast and slow times, checked seed by seed."""
    items = list(per_seed.items()) if isinstance(per_seed, Mapping) else list(enumerate(per_seed))
    if not items:
        raise ValueError("no seeds; allowed: the tables of one or more seeds")
    fast, slow = [], []
    for key, tables in items:
        where = f" in seed {key}" if isinstance(per_seed, Mapping) else f" in tables[{key}]"
        fast.append(_column(tables, "fast", where))
        slow.append(_column(tables, "slow", where))
    return np.asarray(fast), np.asarray(slow)


def _e_of_seeds(fast: np.ndarray, slow: np.ndarray) -> Any:
    """e of the tables averaged over seeds; arrays (..., seeds, cells)."""
    return _quotient(_mean_log_ratio(fast.mean(axis=-2)), _mean_log_ratio(slow.mean(axis=-2)))


_PAIR = 1 + CROWDED.index((1, 1))  # the column of cell (1, 1) in `_column`'s order (alone first)


def _rho_of_seeds(fast: np.ndarray, slow: np.ndarray) -> Any:
    """rho of the tables averaged over seeds; arrays (..., seeds, cells)."""
    return slow.mean(axis=-2)[..., _PAIR] / fast.mean(axis=-2)[..., _PAIR]


def _bootstrap(
    of_seeds: Callable[[np.ndarray, np.ndarray], Any],
    fast: np.ndarray,
    slow: np.ndarray,
    rng: np.random.Generator,
    confidence: float,
    n_resamples: int,
) -> tuple[float, float]:
    """Percentile bootstrap of `of_seeds` (`_e_of_seeds` or `_rho_of_seeds`), resampling seeds
    with replacement (a seed's cells stay together: the resampled objects are seed indices)."""

    def statistic(index: np.ndarray, axis: int = -1) -> Any:
        return of_seeds(fast[index], slow[index])  # index: (..., seeds)

    kwargs: dict[str, Any] = (
        {"rng": rng}
        if "rng" in inspect.signature(stats.bootstrap).parameters
        else {"random_state": rng}  # scipy < 1.15
    )
    res = stats.bootstrap(
        (np.arange(len(fast)),),
        statistic,
        n_resamples=n_resamples,
        batch=1000,
        vectorized=True,
        confidence_level=confidence,
        method="percentile",
        **kwargs,
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def elasticity(
    per_seed: Mapping[int, Tables] | Sequence[Tables],
    rng: np.random.Generator,
    confidence: float = 0.95,
    n_resamples: int = 10_000,
) -> Elasticity:
    """e over seeds (one `Tables` per seed): the point estimate from the tables averaged over
    seeds, a percentile bootstrap interval resampling seeds with draws from `rng` (nan with one
    seed). A ValueError names a missing cell or a bad time and its seed."""
    if not (isinstance(confidence, float) and 0 < confidence < 1):
        raise ValueError(f"confidence = {confidence!r} is invalid; allowed: a float in (0, 1)")
    if not (isinstance(n_resamples, int) and n_resamples >= 1):
        raise ValueError(f"n_resamples = {n_resamples!r} is invalid; allowed: an integer >= 1")
    fast, slow = _arrays(per_seed)
    n = len(fast)
    no_interval = (math.nan, math.nan)
    # e's interval first: the draws for rho come after, so e's interval does not depend on them
    low, high = (
        _bootstrap(_e_of_seeds, fast, slow, rng, confidence, n_resamples) if n >= 2 else no_interval
    )
    rho_low, rho_high = (
        _bootstrap(_rho_of_seeds, fast, slow, rng, confidence, n_resamples)
        if n >= 2
        else no_interval
    )
    return Elasticity(
        e=float(_e_of_seeds(fast, slow)),
        low=low,
        high=high,
        n_seeds=n,
        fast_mean_log_ratio=float(_mean_log_ratio(fast.mean(axis=0))),
        slow_mean_log_ratio=float(_mean_log_ratio(slow.mean(axis=0))),
        confidence=confidence,
        rho=float(_rho_of_seeds(fast, slow)),
        rho_low=rho_low,
        rho_high=rho_high,
        rho_alone=float(slow[:, 0].mean() / fast[:, 0].mean()),
    )
