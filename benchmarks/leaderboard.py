"""The leaderboard: every allocator of the package (random, stay, epsilon and softmax TAVC, response
threshold, auction, greedy, static) on every scenario of the suite (`tavc_env.scenarios`) and its
evaluation seeds; scores normalised between the scenarios' committed references (0 = random, 1 =
the model optimum), interquartile means with bootstrap intervals per scenario and over the suite
(stratified). The study is `tavc_agents.studies.leaderboard`.

Writes `leaderboard.{md,csv,json}`, `leaderboard.png` and every episode under trials/ into a new
run folder under runs/ (git ignores it), `--out`, or with `--update-reference`
benchmarks/results/leaderboard/; `--resume RUN_DIR` continues an interrupted run.

    python benchmarks/leaderboard.py            # 8 allocators x 7 scenarios x 20 seeds of 8 h
    python benchmarks/leaderboard.py --quick    # smoke run
    python benchmarks/leaderboard.py --update-reference --figure-only   # redraw the PNG, run nothing
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import leaderboard as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
