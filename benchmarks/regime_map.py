"""The regime map: fast minus slow time on the high-value circuit (the paper's effect), against
the crowding elasticity e of six arenas and the learner (softmax TAVC at four temperatures,
epsilon-greedy, random), with the model twin's prediction beside every physics cell.

Six arenas: the four shipped `dahl2004` variants, dahl2004_congestion and dahl2004_bays. Measures
each arena's e and twin tables, then runs 400 physics trials (15 h + 5 h) in each cell that decides
the question (softmax T = 0.005 and 0.01 on dahl2004_congestion and dahl2004), 60 in every other
cell and 100 twin trials per cell. Writes `regime_map.{md,csv,json,png}` and `provenance.json` into
a new run folder under runs/ (git ignores it), `--out`, or with `--update-reference`
benchmarks/results/regime_map/; every trial is kept as a compact record under the output folder's
trials/ as it finishes, so `--resume RUN_DIR` continues an interrupted run. The study is
`tavc_agents.studies.regime_map`.

    python benchmarks/regime_map.py --workers 2     # about 3520 physics trials: many hours
    python benchmarks/regime_map.py --quick         # smoke run (a minute or two)
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import regime_map as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
