"""Own or team credit for the deep learners: TorchRL MAPPO trained on the team's reward (every
robot gets the mean reward of the step) on `bad_start`, seeds 0-4, otherwise exactly the deep
leaderboard's runs (`benchmarks/deep_leaderboard.py`), which train each robot on its own
deliveries. The study is `tavc_agents.studies.deep_credit`; it needs the `marl` extra.

Writes the deep leaderboard's report, runs and networks into a new run folder under runs/ (git
ignores it), `--out`, or with `--update-reference` benchmarks/results/deep_credit/. Runs resume.

    python benchmarks/deep_credit.py --update-reference --workers 2   # 5 runs
    python benchmarks/deep_credit.py --quick                          # smoke run
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import deep_credit as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
