"""TAVC against the MRTA baselines the paper lacked, on `dahl2004` and a harder preset.

Random, epsilon-greedy and softmax TAVC, a response-threshold allocator, an auction, greedy on
the model's slot values and static at the model optimum: 10 trials each per preset of 15 h + 5 h
measured. Reports delivered value (also as a fraction of the model optimum), the model value of
the allocation held, switches per robot per hour and time to settle, with 95 % intervals. Writes
allocators.{md,csv,json}, trials.csv and allocators.png into benchmarks/results/allocators/ (or
--out); trials are kept in cache/ so `--resume RUN_DIR` continues an interrupted run. Needs the models of the tavc_model study.
The study is tavc_agents.studies.allocators.

    python benchmarks/allocators.py
    python benchmarks/allocators.py --quick       # a smoke run
    python benchmarks/allocators.py --update-reference --figure-only   # redraw the PNG, run nothing
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import allocators as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
