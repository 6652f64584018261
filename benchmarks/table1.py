"""Reproduce the paper's Table 1, Figure 2 and performance figure (the package's main job).

Softmax TAVC, epsilon-greedy TAVC and random allocation, 15 trials each of 15 simulated hours of
convergence and a 5-hour measured period, in parallel over all cores, each trial saved as it
finishes (`--resume RUN_DIR` continues an interrupted run). Writes table1.{md,csv,json}, figure2.png and performance.png into
benchmarks/results/table1_<preset>_<init>/ (the committed reference; a run writes into a new runs/ folder unless --update-reference or --out). The study is tavc_agents.studies.table1.

    python benchmarks/table1.py                 # full size: 3 x 15 trials x 20 simulated hours
    python benchmarks/table1.py --init paper    # the paper's literal Q initialisation
    python benchmarks/table1.py --quick         # a smoke run in seconds
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import table1 as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
