"""Interference in the arena: task time against crowding, the cost of a circuit switch, and the
cross-interference between fast and slow robots.

Every measurement drives the bare engine (`tavc_env.engine.simulation.Simulation`) with fixed
allocations: each robot serves the circuit it is given, task after task (a designated "switcher"
alternates).

1. **t(n)** (preset `dahl2004_homogeneous`, six robots at 0.25 m/s): allocation k on circuit 0 and
   6 - k on circuit 1 for k = 0..6; one run gives t_0(k) and t_1(6 - k), so seven allocations give
   t(n) for n = 1..6 on both circuits. Also t(n+1)/t(n) with a 95% interval.
2. **Switch cost** (homogeneous): one robot alternates circuits every `--switch-every` tasks while
   the five others stay (three on one circuit, two on the other, both ways round, so every switch
   into a circuit is measured with 3 robots there, i.e. in the 3 + 3 state, and with 4); and a lone
   robot alone in the arena, alternating. A *switch task* starts at the other circuit's sink; its
   time is compared with the same robot's *own-circuit* tasks on the same circuit in the same run
   (same crowding).
3. **Cross-interference** (preset `dahl2004`: robots 0-2 fast 0.30 m/s, 3-5 slow 0.20 m/s): f fast
   and s slow robots on circuit 0 (f, s = 0..3), the rest on circuit 1; the mean task time of a fast
   and of a slow robot on circuit 0 (and, from the same runs, on circuit 1 with 3-f fast, 3-s slow).
4. **Elasticity** e (`tavc_agents.analysis.elasticity`), from the circuit-0 tables T_c(f, s) of 3.:
   mean over f, s in 1..3 of ln(T_fast(f, s) / T_fast(1, 0)) divided by that of
   ln(T_slow(f, s) / T_slow(0, 1)); 1: crowding costs every robot the same fraction of its time,
   > 1: fast robots lose more. Its 95% interval is a percentile bootstrap resampling seeds.
   `tavc_agents.studies.elasticity.measure_elasticity` measures e alone, for any arena.

`--preset` (default dahl2004; also dahl2004_competence, dahl2004_light_stations,
dahl2004_congestion, dahl2004_bays) is the arena of the cross runs; t(n) and the switch runs use
its arena with six robots at 0.25 m/s (for dahl2004: the preset dahl2004_homogeneous).

Warm-up: in every run a task counts only if it was *decided* at or after `--warmup-min` (default
10 simulated minutes) and it is not among the robot's first `--skip-first` (default 2) tasks (the
first task can start at the other circuit's sink, since reset spreads robots 3 + 3 in random
order). Tasks decided up to the end of the run (`--hours`) count, and the run goes on until they
are all complete, so long tasks are not censored at the end. The time each robot spends queued or
travelling is counted tick by tick by an observer of the engine (it changes nothing).

Statistics: each run (seed) gives one number per quantity: the mean over its counted tasks
(task-weighted over the robots of that group). Reported: mean over seeds with a Student-t 95%
interval (n_seeds - 1 df). Ratios t(n+1)/t(n) are ratios of the seed means of two separate sets of
runs; the 95% interval is a delta-method interval on the log scale with Welch-Satterthwaite degrees
of freedom (`tavc_agents.analysis.stats.ratio_ci`); a percentile bootstrap over seeds is given as a
cross-check (too narrow with few seeds). The switch cost is paired within a run: per seed,
mean(switch tasks into c) - mean(own tasks on c), absolute and relative to the own-task mean; mean
over seeds with a Student-t interval.

Writes `interference.{csv,md,json}`, `interference_runs.csv` (one row per run and group) and
`interference.png` (if matplotlib is installed) into a new run folder under runs/ (git ignores it),
`--out`, or with `--update-reference` benchmarks/results/. Runs go through the package's sweep
runner (`--workers`, `--backend local|ray`) and are kept in the output folder's cache/interference/
as they finish, so an interrupted benchmark resumes. The study is `tavc_agents.studies.interference`.

    python benchmarks/interference.py             # 130 runs: 5 seeds x 3 simulated h, ~3-5 min
    python benchmarks/interference.py --quick
    python benchmarks/interference.py --preset dahl2004_competence --out /tmp/competence
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import interference as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
