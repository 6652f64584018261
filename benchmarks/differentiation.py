"""Where does differentiation come from? Softmax temperature and arena regime, measured.

Softmax TAVC at several temperatures, epsilon-greedy TAVC and random allocation in the arena
regimes stations, competence and light_stations; reports, with 95 % confidence intervals over
trials, the time fast and slow robots spend on the high-value circuit, their difference (the
paper's effect: > 0) and performance against random. Trials are saved as they finish and reused
by a rerun. The study is tavc_agents.studies.differentiation.

    python benchmarks/differentiation.py                       # all regimes, default temperatures
    python benchmarks/differentiation.py --regimes stations --temperatures 0.002,0.005,0.02
    python benchmarks/differentiation.py --quick
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import differentiation as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
