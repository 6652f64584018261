"""Elasticity of any arena, measured: `measure_elasticity(config)` runs the fixed-allocation runs e
needs (`tavc_agents.experiments.elasticity`: f fast and s slow robots on circuit 0, for the cells
(1, 0), (0, 1) and f, s in 1..3) as runs of the interference study (`tavc_agents.studies.interference`:
same jobs, keys and group rows) and returns e with its bootstrap interval over seeds
(`tavc_agents.analysis.elasticity`).

    measure_elasticity(tavc_env.preset("dahl2004_competence"), seeds=range(3), hours=2.0)

For a dahl2004 preset the runs are exactly the study's cross runs of that preset, so with the same
seeds and settings e is the one its report gives. The measurement lives here rather than in
`tavc_agents.experiments` because it is made of the analysis's group rows and returns its result
(imports only go down: experiments -> analysis -> studies).
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from tavc_agents.analysis import interference as ia
from tavc_agents.analysis.elasticity import Elasticity, elasticity, seed_tables
from tavc_agents.experiments.elasticity import CELLS, cross_allocation
from tavc_agents.experiments.measurement import FixedAllocation
from tavc_agents.experiments.sweep import run_jobs
from tavc_agents.studies import interference as study
from tavc_env.config import ArenaConfig

BOOT_SEED = study.ELASTICITY_BOOT_SEED
"""the seed of the bootstrap's Generator when none is given (the interference study's)"""


def elasticity_jobs(
    config: ArenaConfig,
    seeds: Iterable[int],
    hours: float,
    warmup_min: float,
    skip_first: int,
) -> list[study.Job]:
    """The interference study's jobs for the runs e needs in `config`'s arena, one per cell and
    seed."""
    if not (math.isfinite(hours) and hours > 0):
        raise ValueError(f"hours = {hours!r} is invalid; allowed: > 0")
    if not (math.isfinite(warmup_min) and warmup_min >= 0):
        raise ValueError(f"warmup_min = {warmup_min!r} is invalid; allowed: >= 0")
    if not (isinstance(skip_first, int) and skip_first >= 0):
        raise ValueError(f"skip_first = {skip_first!r} is invalid; allowed: an integer >= 0")
    jobs = []
    for seed in seeds:
        for f, s in CELLS:
            alloc = cross_allocation(
                config,
                f,
                s,
                seed=seed,
                hours=hours,
                warmup_s=warmup_min * 60.0,
                skip_first=skip_first,
            )
            alloc.config()  # a bad arena is refused before any run
            fields = {x.name: getattr(alloc, x.name) for x in dataclasses.fields(FixedAllocation)}
            jobs.append(study.Job(experiment="cross", label=ia.cross_label(f, s), **fields))
    return jobs


def measure_elasticity(
    config: ArenaConfig,
    seeds: Iterable[int] = range(5),
    hours: float = 3.0,
    *,
    warmup_min: float = 10.0,
    skip_first: int = 2,
    workers: int | None = None,
    out: Path | None = None,
    rng: np.random.Generator | None = None,
) -> Elasticity:
    """e of `config`'s arena with a 95 % percentile-bootstrap interval over `seeds`.

    Each seed runs the 11 cells e needs for `hours` simulated hours (a task counts if decided at
    or after `warmup_min` minutes and not among the robot's first `skip_first`), the defaults
    being the interference study's. `workers`: processes (default: all cores). `out`: a folder
    that keeps the runs (a later call with the same settings resumes them; default: a temporary
    folder). `rng`: the bootstrap's Generator (default: seeded with `BOOT_SEED`)."""
    seed_list = list(seeds)
    if not seed_list or not all(isinstance(s, int) and s >= 0 for s in seed_list):
        raise ValueError(f"seeds = {seed_list!r} is invalid; allowed: one or more integers >= 0")
    jobs = elasticity_jobs(config, seed_list, hours, warmup_min, skip_first)
    with tempfile.TemporaryDirectory(prefix="elasticity-") as tmp:
        results = run_jobs(jobs, study.RUNS, out if out is not None else tmp, workers)
    rows = [r for job in jobs for r in results[study.job_key(job)]["rows"]]
    boot = rng if rng is not None else np.random.default_rng(BOOT_SEED)
    return elasticity(seed_tables(rows, seed_list), boot)
