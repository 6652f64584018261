"""Re-run saved trials from their stored settings and check that they come out bit for bit the same.

Compares everything a trial recorded (timeline, deliveries, Q snapshots, counters; not the
wall-clock time). Exit status 1 if any trial differs. The study is tavc_agents.studies.reproduce.

    python benchmarks/reproduce_trials.py benchmarks/results/table1_dahl2004_scaled/trials/*.json
    python benchmarks/reproduce_trials.py --sample 4 --seed 1 'benchmarks/results/*/trials/*.json'
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import parse_settings
from tavc_agents.studies import reproduce as study


def main(argv: Sequence[str] | None = None) -> int:
    settings = parse_settings(study.Settings, argv, __doc__ or "")
    outcome = study.run(settings)
    print(outcome.text)
    return 0 if study.all_reproduced(outcome) else 1


if __name__ == "__main__":
    raise SystemExit(main())
