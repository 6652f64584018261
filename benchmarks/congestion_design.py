"""The design search for a congestion arena: which physical mechanisms (the clearance governor,
the loading time, station bays) give crowding elasticity e <= 1 while t(4)/t(3) >= 1.1 keeps
3 + 3 the homogeneous equilibrium? Fixed allocations only, no learning; the rules that pick the
arenas (`dahl2004_congestion`, and `dahl2004_bays` for the regime map) are in the study's
docstring (`tavc_agents.studies.congestion_design`).

Writes `congestion_design.{md,csv,json}` and every run (`runs/`) into a new run folder under
runs/ (git ignores it), `--out`, or with `--update-reference` benchmarks/results/congestion_design/
(congestion_design_bays/ for the second search, congestion_design_passing/ for the third);
`--resume RUN_DIR` continues an interrupted run.

    python benchmarks/congestion_design.py                 # 15 candidates x 3 seeds x 2 h
    python benchmarks/congestion_design.py --search bays   # the second search: 12 candidates
    python benchmarks/congestion_design.py --search passing  # the third: 18 candidates x 5 seeds
    python benchmarks/congestion_design.py --quick         # smoke run
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import congestion_design as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
