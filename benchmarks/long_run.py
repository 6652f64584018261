"""Long-run health of the arena: many simulated hours of `dahl2004` with random circuit choices.

Drives the PettingZoo env (`tavc_env.parallel_env(preset="dahl2004")`, event-driven stepping) with
uniformly random circuit choices for every robot that must decide (seeded), and records every task
completion. Reports, per robot, the number of tasks and the longest gap between two completions
(also counting the start of the run to the first completion and the last completion to the end),
where and when it happened; the number of steps that hit the step cap (a step that returns with
nobody deciding); the minimum centre-to-centre distance between robots and the minimum robot-wall
clearance, sampled after every physics tick by an observer of the engine; and the wall time.

Exits with status 1 if any robot's longest gap exceeds `--max-gap-min` (default 30 simulated
minutes): a robot that stops completing tasks is a jam or a stuck robot.

Writes `long_run.{csv,md,json}` (per robot summary) and `long_run_tasks_seed<S>.csv` (every
completion, written as the run goes) into a new run folder under runs/ (git ignores it), `--out`,
or with `--update-reference` benchmarks/results/. Seeds run through the package's sweep runner
(`--workers`, `--backend local|ray`) and are kept in the output folder's cache/long_run/, so
`--resume RUN_DIR` continues an interrupted run. The study is `tavc_agents.studies.long_run`.

    python benchmarks/long_run.py                 # 15 simulated hours, seeds 0-3 (~1-2 min wall)
    python benchmarks/long_run.py --quick         # smoke run
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import long_run as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
