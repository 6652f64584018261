"""The decisive test of emergent differentiation where robots can pass (`dahl2004_passing`), in two
stages: `--stage predict` measures the arena's e, rho and twin tables and commits the batched twin's
prediction of fast - slow with the physics trials each cell needs for 80 % power (the plan);
`--stage test` runs exactly those physics trials (resumable) and sets each result beside its
prediction. The study is `tavc_agents.studies.passing`.

Writes `prediction.{md,csv,json}` and `prediction_trials.csv` (predict), or `passing.{md,csv,json}`
and every trial under trials/ (test), into a new run folder under runs/ (git ignores it), `--out`,
or with `--update-reference` benchmarks/results/passing_prediction/ or benchmarks/results/passing/;
`--resume RUN_DIR` continues an interrupted run.

    python benchmarks/passing.py --stage predict    # minutes: e, twin tables, 5 x 2000 twin trials
    python benchmarks/passing.py --stage test       # hours: about a thousand 20-h physics trials
    python benchmarks/passing.py --quick --arena dahl2004_bays   # smoke run
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import passing as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
