"""The model twin's fast - slow against the crowding elasticity e, on synthetic tables of e from 0.75
to 2.0 (2000 batched twin trials per point and condition: softmax TAVC at T = 0.002, 0.005, 0.01,
epsilon 0.1; 15 h + 5 h), the break-even e per condition, and the figure of the differentiation
page: these curves, the regime map's physics cells and the dahl2004_passing prediction and result
where committed. The design is in the study's docstring (`tavc_agents.studies.twin_curve`).

Writes `twin_curve.{md,csv,json}`, `twin_curve_trials.csv` and `differentiation.png` into a new
run folder (`--update-reference`: benchmarks/results/twin_curve/); `--resume RUN_DIR` continues.

    python benchmarks/twin_curve.py --workers 2        # 56 batches of 2000 trials: about 15 min
    python benchmarks/twin_curve.py --quick            # smoke run (seconds)
    python benchmarks/twin_curve.py --update-reference --figure-only   # redraw, run nothing
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import twin_curve as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
