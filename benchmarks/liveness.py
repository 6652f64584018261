"""Liveness at length: the jam rate and the longest gap per robot over team sizes and random arenas.

Runs the PettingZoo env with uniformly random circuit choices (`RandomAllocator` through
`tavc_agents.experiments.runner.run_trial`) in three arms: `dahl2004` with k fast + k slow robots
(k = 3..6; a team of 14 is refused, and the report quotes why), two-lane arenas
`tavc_env.scaled_config(2, rpc)` with rpc = 3, 6, 12, 18, 24 robots per circuit (4 simulated hours
x 4 seeds each), and 120 random valid arenas (`tavc_agents.experiments.arenas`; 2 h x 1 seed each).
Counts the jams the engine's detector finds and every robot's longest gap without a delivery.

Reports the jam rate with an exact (Clopper-Pearson) 95 % interval overall, per arm and per team
size, the longest gap per team size and overall, the random arenas' refused draws by reason, and
the wall time. Exits with status 1 if any trial has an unreported jam: a robot longer than
`--max-gap-min` (default 60 simulated minutes) without a delivery while the detector found none.

Writes `liveness.{md,csv,json}` (one CSV row per trial) and `provenance.json` into a new run folder
under runs/ (git ignores it), `--out`, or with `--update-reference` benchmarks/results/liveness/;
each trial is kept as a small record in the output folder's trials/ as it finishes, so `--resume
RUN_DIR` continues an interrupted run (`--workers`, `--backend local|ray`). The study is
`tavc_agents.studies.liveness`.

    python benchmarks/liveness.py                 # 156 trials, ~5 min on one core
    python benchmarks/liveness.py --quick         # smoke run (seconds)
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import liveness as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
