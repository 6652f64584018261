"""The scenario suite's references (`tavc_env.scenarios`): `--stage predict` computes, from the
measured TAVC models alone, every scenario's random, stay and optimum value per hour on its
evaluation seeds and the predicted headroom (1 - stay / optimum); `--stage measure` runs the physics
episodes of random, stay and the static model optimum on those seeds and writes the reference
table the leaderboard normalises with. The study is `tavc_agents.studies.scenarios`.

Writes `prediction.{md,csv,json}` (predict) or `references.{md,csv,json}` and every episode under
trials/ (measure) into a new run folder under runs/ (git ignores it), `--out`, or with
`--update-reference` benchmarks/results/scenarios_prediction/ or benchmarks/results/scenarios/;
`--resume RUN_DIR` continues an interrupted run.

    python benchmarks/scenarios.py --stage predict     # seconds, no physics
    python benchmarks/scenarios.py --stage measure     # minutes: 3 x 20 episodes per scenario
    python benchmarks/scenarios.py --quick --stage measure   # smoke run
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import scenarios as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
