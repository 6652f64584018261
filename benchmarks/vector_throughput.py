"""Decisions per second of the vectorised views with 1 and 2 worker processes, in wall time, in one
run: `gymnasium.make_vec("tavc/dahl2004-v0", ...)` (the single-robot view) sync 1, async 1 and
async 2, and the batched multi-agent view (`tavc_env.adapters.batched.BatchedArenaEnv`) in-process
and with 1 and 2 workers, for each of `--arenas-per-worker` (default 4 and 16 arenas per worker).
Every round also measures the machine's ceiling (two independent processes stepping the
single-robot view, over one) and reports each 2-worker ratio as a share of it, with the measured
parts that explain the gap (the workers' step cost and its spread, measured in-process; the
parent's CPU per vector step). Ratios are to the 1-worker figure of the same round; goal (issue 26):
2 workers >= 1.6 x 1 in both views (exit status 1 if missed). Writes `vector_throughput.{csv,md,json}`
into a new run folder under runs/ (git ignores it), `--out`, or with `--update-reference`
benchmarks/results/vector_throughput/. The study is `tavc_agents.studies.vector_throughput`.

    python benchmarks/vector_throughput.py               # a few minutes on 2 idle cores
    python benchmarks/vector_throughput.py --quick
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import vector_throughput as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
