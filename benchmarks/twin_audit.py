"""The model twin audited under random allocation: are its tables' own-circuit cells and its switch
cost right where crowds change at every decision, and how much of its disagreement with the
physics on random allocation does the switch cost explain? The design is in the study's docstring
(`tavc_agents.studies.twin_audit`).

Writes `twin_audit.{md,csv,json,png}`, every run (`runs/`) and the arenas' tables (`twin_tables/`)
into a new run folder (`--update-reference`: benchmarks/results/twin_audit/); `--resume RUN_DIR`
continues an interrupted run.

    python benchmarks/twin_audit.py           # 6 arenas x (10 physics + 2 x 40 twin runs) of 4 h
    python benchmarks/twin_audit.py --quick   # smoke run
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import twin_audit as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
