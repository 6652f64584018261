"""Elasticity: tables with a known e (multiplicative crowding gives 1, additive waits more than 1,
waits that grow with the robot's slowness less than 1), the bootstrap interval over seeds, bad
tables refused by name, the tables read from cross rows, the runs for any arena, e from the
committed interference runs, and a short real measurement."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import arena_analysis as ea
import arena_analysis as ia
import interference as study
import tavc_env
from arena_runs import elasticity_jobs, measure_elasticity
from tavc_env.config import lane_circuits

ROOT = Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "benchmarks" / "results"
Time = Callable[[str, int, int], float]


def _tables(time: Time) -> ea.Tables:
    """Tables over every cell f, s in 0..3 where the class is present."""
    cells = [(f, s) for f in range(4) for s in range(4)]
    return ea.Tables(
        {(f, s): time("fast", f, s) for f, s in cells if f >= 1},
        {(f, s): time("slow", f, s) for f, s in cells if s >= 1},
    )


BASE = {"fast": 60.0, "slow": 90.0}


def _multiplicative(cls: str, f: int, s: int) -> float:
    return BASE[cls] * (1.0 + 0.15 * (f + s - 1) + 0.02 * f * s)


def _additive(cls: str, f: int, s: int) -> float:
    return BASE[cls] + 12.0 * (f + s - 1)  # the same seconds of waiting for everyone


def _slow_lose_more(cls: str, f: int, s: int) -> float:
    wait = {"fast": 4.0, "slow": 25.0}[cls]  # waits that grow with the robot's own slowness
    return BASE[cls] + wait * (f + s - 1)


def _expected(time: Time) -> float:
    def mean_log(cls: str, alone: tuple[int, int]) -> float:
        return float(
            np.mean([math.log(time(cls, f, s) / time(cls, *alone)) for f, s in ea.CROWDED])
        )

    return mean_log("fast", (1, 0)) / mean_log("slow", (0, 1))


def test_multiplicative_crowding_gives_one() -> None:
    tables = _tables(_multiplicative)
    assert ea.elasticity_of(tables) == pytest.approx(1.0, rel=1e-12)
    fast, slow = ea.log_ratios(tables)
    assert fast == pytest.approx(slow, rel=1e-12) and fast > 0


def test_additive_waits_cost_fast_robots_more() -> None:
    e = ea.elasticity_of(_tables(_additive))
    assert e > 1.2
    assert e == pytest.approx(_expected(_additive), rel=1e-12)


def _held_to_slow_pace(cls: str, f: int, s: int) -> float:
    # with a slow robot on the circuit every robot works at the slow robot's pace
    return BASE["slow" if s else cls] * (1.0 + 0.1 * (f + s - 1))


def test_pace_in_company_is_one_when_the_fast_robot_is_held_back() -> None:
    held = ea.elasticity([_tables(_held_to_slow_pace)] * 3, np.random.default_rng(0))
    assert held.rho == pytest.approx(1.0, rel=1e-12)
    assert held.rho_alone == pytest.approx(BASE["slow"] / BASE["fast"], rel=1e-12)
    free = ea.elasticity([_tables(_multiplicative)] * 3, np.random.default_rng(0))
    assert free.rho == pytest.approx(free.rho_alone, rel=1e-12)  # crowding costs both alike
    assert free.rho_text(2) == "1.50 [1.50, 1.50]"


def test_pace_interval_is_drawn_after_e_so_e_is_unchanged() -> None:
    rng = np.random.default_rng(3)
    noisy = [_tables(lambda c, f, s, k=k: _additive(c, f, s) * (1 + 0.03 * k)) for k in range(4)]
    for k, t in enumerate(noisy):
        t.slow[(1, 1)] *= 1 + 0.05 * (k % 2)  # some spread in rho too
    el = ea.elasticity(noisy, rng, n_resamples=300)
    low, high = ea._bootstrap(
        ea._e_of_seeds, *ea._arrays(noisy), np.random.default_rng(3), 0.95, 300
    )
    assert (el.low, el.high) == (low, high)
    assert el.rho_low < el.rho < el.rho_high


def test_waits_growing_with_slowness_cost_slow_robots_more() -> None:
    e = ea.elasticity_of(_tables(_slow_lose_more))
    assert e < 0.8
    assert e == pytest.approx(_expected(_slow_lose_more), rel=1e-12)


def test_e_over_seeds_without_noise_is_that_of_each_seed() -> None:
    per_seed = {seed: _tables(_additive) for seed in range(4)}
    el = ea.elasticity(per_seed, np.random.default_rng(0), n_resamples=200)
    assert el.e == pytest.approx(_expected(_additive), rel=1e-12)
    assert el.low == pytest.approx(el.e) and el.high == pytest.approx(el.e)
    assert el.n_seeds == 4
    assert el.fast_mean_log_ratio / el.slow_mean_log_ratio == pytest.approx(el.e)
    assert el.text().startswith(f"{el.e:.3f} [")


def _noisy_seeds(n: int, rng: np.random.Generator, sd: float = 0.03) -> dict[int, ea.Tables]:
    """Additive crowding with independent lognormal noise on every cell of every seed."""
    out = {}
    for seed in range(n):
        clean = _tables(_additive)
        out[seed] = ea.Tables(
            {c: v * math.exp(rng.normal(0, sd)) for c, v in clean.fast.items()},
            {c: v * math.exp(rng.normal(0, sd)) for c, v in clean.slow.items()},
        )
    return out


def test_bootstrap_interval_holds_the_estimate_and_shrinks_with_more_seeds() -> None:
    pool = _noisy_seeds(96, np.random.default_rng(2))
    widths = []
    for n in (6, 24, 96):
        el = ea.elasticity({s: pool[s] for s in range(n)}, np.random.default_rng(1))
        assert el.low < el.e < el.high
        assert el.n_seeds == n
        widths.append(el.high - el.low)
    assert widths[0] > widths[1] > widths[2]  # about 1 / sqrt(seeds)
    assert widths[2] < 0.5 * widths[0]
    assert el.low < _expected(_additive) < el.high


def test_bootstrap_is_reproducible_from_its_generator() -> None:
    seeds = _noisy_seeds(5, np.random.default_rng(3))
    a = ea.elasticity(seeds, np.random.default_rng(7), n_resamples=500)
    b = ea.elasticity(seeds, np.random.default_rng(7), n_resamples=500)
    c = ea.elasticity(seeds, np.random.default_rng(8), n_resamples=500)
    assert a == b and (a.low, a.high) != (c.low, c.high) and a.e == c.e


def test_one_seed_has_no_interval() -> None:
    el = ea.elasticity([_tables(_additive)], np.random.default_rng(0))
    assert el.n_seeds == 1 and math.isnan(el.low) and math.isnan(el.high)
    assert el.text() == f"{el.e:.3f}"


def test_no_crowding_cost_for_slow_robots_leaves_e_undefined() -> None:
    def flat_slow(cls: str, f: int, s: int) -> float:
        return BASE[cls] if cls == "slow" else _additive(cls, f, s)

    assert math.isnan(ea.elasticity_of(_tables(flat_slow)))


def _without(tables: ea.Tables, cls: str, cell: tuple[int, int]) -> ea.Tables:
    fast, slow = dict(tables.fast), dict(tables.slow)
    del (fast if cls == "fast" else slow)[cell]
    return ea.Tables(fast, slow)


def _with(tables: ea.Tables, cls: str, cell: tuple[int, int], value: Any) -> ea.Tables:
    fast, slow = dict(tables.fast), dict(tables.slow)
    (fast if cls == "fast" else slow)[cell] = value
    return ea.Tables(fast, slow)


@pytest.mark.parametrize(("cls", "cell"), [("fast", (2, 3)), ("fast", (1, 0)), ("slow", (0, 1))])
def test_a_missing_cell_is_named(cls: str, cell: tuple[int, int]) -> None:
    bad = _without(_tables(_additive), cls, cell)
    with pytest.raises(ValueError, match=rf"^T_{cls}\({cell[0]}, {cell[1]}\) is missing; "):
        ea.elasticity_of(bad)
    per_seed = {0: _tables(_additive), 4: bad}
    with pytest.raises(ValueError, match=rf"T_{cls}\({cell[0]}, {cell[1]}\) is missing in seed 4"):
        ea.elasticity(per_seed, np.random.default_rng(0))


@pytest.mark.parametrize("value", [0.0, -5.0, math.nan, math.inf, None, "60"])
def test_a_time_that_is_not_positive_and_finite_is_named(value: Any) -> None:
    bad = _with(_tables(_additive), "slow", (3, 1), value)
    with pytest.raises(ValueError, match=r"^T_slow\(3, 1\) = .* is invalid; allowed: a finite"):
        ea.elasticity_of(bad)
    with pytest.raises(ValueError, match=r"T_slow\(3, 1\) = .* in tables\[1\] is invalid"):
        ea.elasticity([_tables(_additive), bad], np.random.default_rng(0))


def test_bad_arguments_are_refused() -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match=r"^no seeds"):
        ea.elasticity({}, rng)
    with pytest.raises(ValueError, match=r"^confidence = "):
        ea.elasticity([_tables(_additive)] * 2, rng, confidence=95.0)
    with pytest.raises(ValueError, match=r"^n_resamples = "):
        ea.elasticity([_tables(_additive)] * 2, rng, n_resamples=0)
    with pytest.raises(ValueError, match="no row of a 'cross' run"):
        ea.seed_tables([{"experiment": "t_n", "seed": 0}])


# -- from the interference measurement's rows ---------------------------------------------------
def _cross_rows(time: Time, seeds: range) -> list[dict[str, Any]]:
    rows = []
    for seed in seeds:
        for f in range(4):
            for s in range(4):
                for c, nf, ns in ((0, f, s), (1, 3 - f, 3 - s)):
                    for cls, n in (("fast", nf), ("slow", ns), ("all", nf + ns)):
                        if n == 0:
                            continue
                        t = time(cls, nf, ns) if cls != "all" else 1.0
                        rows.append(
                            {
                                "experiment": "cross",
                                "label": ia.cross_label(f, s),
                                "seed": seed,
                                "circuit": c,
                                "robot_class": cls,
                                "task_kind": "own",
                                # circuit 1 differs: only circuit 0 may enter the tables
                                "mean_task_time_s": t + seed + (1000.0 if c == 1 else 0.0),
                            }
                        )
    return rows


def test_tables_come_from_circuit_zero_of_the_cross_runs() -> None:
    rows = _cross_rows(_additive, range(3))
    rows.append({**rows[0], "experiment": "t_n"})  # other experiments are not read
    tables = ea.seed_tables(rows)
    assert sorted(tables) == [0, 1, 2]
    assert tables[2].fast[(2, 3)] == _additive("fast", 2, 3) + 2
    assert tables[0].slow[(0, 1)] == _additive("slow", 0, 1)
    assert set(tables[0].fast) == {(f, s) for f in range(1, 4) for s in range(4)}
    assert set(tables[0].slow) == {(f, s) for f in range(4) for s in range(1, 4)}
    assert sorted(ea.seed_tables(rows, [2, 0])) == [0, 2]
    el = ea.elasticity(ea.seed_tables(rows, [0]), np.random.default_rng(0))
    assert el.e == pytest.approx(_expected(_additive), rel=1e-12)
    # a seed without its runs: the missing cell is named
    with pytest.raises(ValueError, match=r"T_fast\(1, 0\) is missing in seed 9"):
        ea.elasticity(ea.seed_tables(rows, [0, 9]), np.random.default_rng(0))


@pytest.mark.parametrize("folder", ["", "interference_competence", "interference_light_stations"])
def test_committed_interference_runs_give_e(folder: str) -> None:
    """The committed runs hold every cell; e there is well above 1 (fast robots lose more)."""
    rows = ia.read_group_rows(COMMITTED / folder / "interference_runs.csv")
    tables = ea.seed_tables(rows)
    el = ea.elasticity(tables, np.random.default_rng(study.ELASTICITY_BOOT_SEED))
    assert el.n_seeds == (5 if folder == "" else 3)
    assert 1.5 < el.e < 4.0 and el.low <= el.e <= el.high
    assert el.fast_mean_log_ratio > el.slow_mean_log_ratio > 0


# -- the runs, for any arena --------------------------------------------------------------------
def test_cross_runs_of_the_dahl2004_presets_are_the_studys_own() -> None:
    for preset, overrides in (
        ("dahl2004", ()),
        ("dahl2004_competence", (("service_scales_with_speed", True),)),
        ("dahl2004_light_stations", (("sink_service_s", 2.0), ("source_service_s", 6.0))),
    ):
        for f, s in ea.CELLS:
            alloc = ea.cross_allocation(
                tavc_env.preset(preset), f, s, seed=1, hours=3.0, warmup_s=600.0, skip_first=2
            )
            assert alloc.arena == overrides
            assert alloc.config() == tavc_env.preset(preset)
            assert alloc.circuit_of == tuple([0] * f + [1] * (3 - f) + [0] * s + [1] * (3 - s))
    # the study's jobs of the same cell: the same run
    s = study.Settings(preset="dahl2004_competence")
    cross = next(j for j in study.make_jobs(s) if j.label == "2:1" and j.seed == 0)
    assert cross.allocation().config() == tavc_env.preset("dahl2004_competence")
    mine = next(
        j for j in elasticity_jobs(tavc_env.preset(s.preset), [0], 3.0, 10.0, 2) if j.label == "2:1"
    )
    assert mine.allocation().config() == cross.allocation().config()
    assert mine.circuit_of == cross.circuit_of and study.job_key(mine) == study.job_key(cross)


def test_cross_runs_in_other_arenas() -> None:
    three = tavc_env.preset("three_circuits_three_classes")  # nine robots, three circuits
    alloc = ea.cross_allocation(three, 2, 1, seed=0, hours=1.0, warmup_s=0.0, skip_first=0)
    config = alloc.config()
    assert config.robots == (ea.FAST,) * 3 + (ea.SLOW,) * 3
    assert config.circuits == three.circuits and config.width == three.width
    one = tavc_env.make_config(circuits=lane_circuits(1, values=(1000.0,)))
    alloc = ea.cross_allocation(one, 2, 1, seed=0, hours=1.0, warmup_s=0.0, skip_first=0)
    assert alloc.circuit_of == (0, 0, 0)
    assert alloc.config().robots == (ea.FAST, ea.FAST, ea.SLOW)
    with pytest.raises(ValueError, match=r"^fast = 4 is invalid"):
        ea.cross_allocation(one, 4, 1, seed=0, hours=1.0, warmup_s=0.0, skip_first=0)
    with pytest.raises(ValueError, match=r"^fast = slow = 0 is invalid"):
        ea.cross_circuits(0, 0, 2)
    with pytest.raises(ValueError, match=r"^config = .* is invalid"):
        ea.cross_arena("dahl2004", 1, 1)  # type: ignore[arg-type]


def test_the_study_takes_a_preset() -> None:
    default = study.make_jobs(study.Settings())
    assert {j.preset for j in default} == {"dahl2004", "dahl2004_homogeneous"}
    assert "preset" not in study.Settings().recorded()  # the committed reports' settings
    s = study.Settings(preset="dahl2004_light_stations")
    assert s.recorded()["preset"] == "dahl2004_light_stations"
    jobs = study.make_jobs(s)
    homog = tavc_env.make_config("dahl2004_homogeneous", source_service_s=6.0, sink_service_s=2.0)
    for job in jobs:
        config = job.allocation().config()
        if job.experiment == "cross":
            assert config == tavc_env.preset("dahl2004_light_stations")
        elif job.experiment != "switch_lone":
            assert config == homog
    with pytest.raises(ValueError, match=r"^preset = 'dahl2004_homogeneous' is invalid; allowed"):
        study.Settings(preset="dahl2004_homogeneous")


# -- a real measurement -------------------------------------------------------------------------
def test_measure_elasticity_runs_the_cells_and_resumes(tmp_path: Path) -> None:
    config = tavc_env.preset("dahl2004")
    kwargs: dict[str, Any] = {"hours": 0.1, "warmup_min": 0.5, "skip_first": 1, "workers": 2}
    el = measure_elasticity(config, seeds=[0, 1], out=tmp_path, **kwargs)
    assert el.n_seeds == 2 and math.isfinite(el.e) and el.e > 0
    assert el.low <= el.e <= el.high
    assert len(list(tmp_path.glob("cross_*.json"))) == 2 * len(ea.CELLS) == 22
    again = measure_elasticity(config, seeds=[0, 1], out=tmp_path, **kwargs)  # all resumed
    assert again == el
    with pytest.raises(ValueError, match=r"^seeds = "):
        measure_elasticity(config, seeds=[])
    with pytest.raises(ValueError, match=r"^hours = "):
        measure_elasticity(config, hours=0.0)


def test_measure_elasticity_in_an_arena_of_one_circuit() -> None:
    one = tavc_env.make_config(circuits=lane_circuits(1, values=(1000.0,)))
    el = measure_elasticity(one, seeds=[0], hours=0.1, warmup_min=0.5, skip_first=1, workers=2)
    assert el.n_seeds == 1 and math.isfinite(el.e) and el.e > 0 and math.isnan(el.low)
