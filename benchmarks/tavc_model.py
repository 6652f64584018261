"""The TAVC model measured: completion frequencies, slot values, the predicted optimum, and a check.

Every group of robots serves every circuit alone (fixed allocations) to measure its
task-completion frequency c; Equation 1 gives the slot values and exhaustive search the
model-optimal allocation, which then runs, with its neighbours and the next-best allocations, as a
static allocation in the full arena to check the prediction. Writes model.json (read by
allocators.py and vacancy_chain.py), slot_values.{md,csv,json}, group_runs.csv and
check.{md,csv,json} into benchmarks/results/tavc_model/<preset>/ (or --out); runs are kept in
cache/ so a rerun resumes. The study is agents.studies.tavc_model.

    python benchmarks/tavc_model.py                                        # dahl2004
    python benchmarks/tavc_model.py --preset three_circuits_three_classes --seeds 2
"""

from __future__ import annotations

from collections.abc import Sequence

from agents.studies import tavc_model as study
from agents.studies.common import parse_settings


def main(argv: Sequence[str] | None = None) -> int:
    settings = parse_settings(study.Settings, argv, __doc__ or "")
    outcome = study.run(settings)
    print(outcome.text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
