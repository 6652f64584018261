"""The batched model twin (thousands of twin trials in seconds, for power analyses) checked
against the Policy-based twin in every cell of the regime map, and timed against the physics. The
design is in the study's docstring (`tavc_agents.studies.twin_batch`).

Writes `twin_batch.{md,csv,json}` and every cell's batch (`cells/`) into a new run folder
(`--update-reference`: benchmarks/results/twin_batch/); `--resume RUN_DIR` continues.

    python benchmarks/twin_batch.py           # 36 cells x 2000 trials, then the speed timing
    python benchmarks/twin_batch.py --quick   # smoke run
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import twin_batch as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
