"""The deep-MARL leaderboard: TorchRL MAPPO and IPPO (one actor shared by every robot) trained for
one budget of robot decisions on the paper's scenario and the three with the most headroom
(`dahl2004`, `passing`, `three_circuits`, `bad_start`), training seeds 0-4, then run greedily on
each scenario's evaluation seeds; interquartile means with bootstrap intervals over training seeds,
beside `stay` and the best allocator. The study is `tavc_agents.studies.deep_leaderboard`; it needs
the `marl` extra.

Writes `deep_leaderboard.{md,csv,json}`, `deep_leaderboard.png`, every run under runs/ and its
network under networks/ into a new run folder under runs/ (git ignores it), `--out`, or with
`--update-reference` benchmarks/results/deep_leaderboard/. Runs resume: a rerun into the same
folder skips the saved runs; `--max-jobs N` runs at most N new ones (0: only the report).

    python benchmarks/deep_leaderboard.py --update-reference --workers 2   # 40 runs
    python benchmarks/deep_leaderboard.py --quick                          # smoke run
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import deep_leaderboard as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
