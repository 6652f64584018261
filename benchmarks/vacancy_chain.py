"""Vacancy chains: a breakdown, a repair and a priority change after convergence.

After 15 h on `dahl2004` a fast robot on the high-value circuit breaks down, 3 h later it is
repaired, 3 h later the circuits' values swap; a paired control trial without events runs beside
each. Reports per allocator how fast the vacancy is refilled (and by whom), the value lost, and
how well the allocation follows the priority change. Writes vacancy_chain.{md,csv,json},
trials.csv and timeline.png into benchmarks/results/vacancy_chain/ (the committed reference; a run writes into a new runs/ folder unless --update-reference or --out); trials are kept in
cache/ so `--resume RUN_DIR` continues an interrupted run. Needs the dahl2004 model of the tavc_model study. The study is
tavc_agents.studies.vacancy_chain.

    python benchmarks/vacancy_chain.py
    python benchmarks/vacancy_chain.py --quick
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import vacancy_chain as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
