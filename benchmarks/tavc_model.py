"""The TAVC model measured: completion frequencies, slot values, the predicted optimum, and a check.

Every group of robots serves every circuit alone (fixed allocations) to measure its
task-completion frequency c; Equation 1 gives the slot values and exhaustive search the
model-optimal allocation, which then runs, with its neighbours and the next-best allocations, as a
static allocation in the full arena to check the prediction. Writes model.json (read by the
model-based allocators, allocators.py and vacancy_chain.py), slot_values.{md,csv,json},
group_runs.csv and check.{md,csv,json} into a new runs/ folder (or --out); with
--update-reference, the reports into benchmarks/results/tavc_model/<preset>/ and the model into
the package data the allocators read, agents/tavc_agents/data/models/<preset>.json; runs are kept in
cache/ so `--resume RUN_DIR` continues an interrupted run. The study is tavc_agents.studies.tavc_model.

    python benchmarks/tavc_model.py                                        # dahl2004
    python benchmarks/tavc_model.py --preset three_circuits_three_classes --seeds 2
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import tavc_model as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
