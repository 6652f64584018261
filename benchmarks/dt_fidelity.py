"""Does the physics time step change the results? Task times and the interference curve at several dt.

For each physics step `dt` (default 0.05, 0.1, 0.2 and 0.25 s) and each seed:

1. the interference curve t(n), n = 1..6, of the homogeneous arena (`dahl2004_homogeneous`, fixed
   allocations, exactly the runs of `interference.py`'s first experiment);
2. the mean task time of fast and of slow robots in `dahl2004` under random allocation.

Each quantity at each dt is compared with the finest step (a ratio of seed means with a 95 %
interval, `tavc_agents.analysis.stats.ratio_ci`); a step passes when every quantity is within
`--tolerance` (3 %) of the finest. The package's default step is the largest that passes. Outputs
in `benchmarks/results/dt_fidelity/` (the committed reference; a run writes into a new `runs/` folder unless `--update-reference` or `--out`): `dt_fidelity.{md,csv,json}`; runs are kept in
`cache/` as they finish, so `--resume RUN_DIR` continues an interrupted run. The study is `tavc_agents.studies.dt_fidelity`.

    python benchmarks/dt_fidelity.py            # 160 runs of 3 simulated h, ~4 min on 2 cores
    python benchmarks/dt_fidelity.py --quick
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import dt_fidelity as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
