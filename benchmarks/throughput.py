"""Throughput of the arena at 6, 24 and 96 robots (and 384), in CPU time, against two yardsticks
of the same physics.

Each case (`dahl2004` for 6 robots; `tavc_env.scaled_config(n_circuits, 3)` for 24, 96 and 384:
8, 32 and 128 lanes of three robots; event-driven stepping, and for `--fixed-sizes` one env step
every `--interval-s` simulated seconds) runs in a process of its own, every robot that must decide
picking a circuit uniformly at random (seeded):

* `env`: the PettingZoo parallel env: simulated seconds, ticks and decisions per CPU second;
* `replay`: the env's own velocity commands of the same run, recorded, then set tick after tick
  on a bare pymunk world of the same bodies (it must end exactly where the env ended);
* `bare loop`: the same bodies (same radius, mass, dt, solver iterations, walls) placed as at
  reset, each velocity set once, then `space.step(dt)` as many ticks as the env ran.

Times are CPU seconds of the measuring process (`time.process_time`), so other processes on a
shared machine do not count; the cases take turns round after round (`--repeats`), and the
machine's load average is recorded with every row. Reported: speeds, env / replay and env / bare
loop (ticks per CPU second, paired by round), peak memory. Goal (issue 24): at 6 robots at least
0.95 of the bare loop and 0.5 of the replay; the exit status is 1 if it is missed. Writes
`throughput.{csv,md,json}` into a new run folder under runs/ (git ignores it), `--out`, or with
`--update-reference` benchmarks/results/throughput/. The study is `tavc_agents.studies.throughput`.

    python benchmarks/throughput.py                # ~3 min
    python benchmarks/throughput.py --dt 0.2 --sizes 6 96 --out benchmarks/results/throughput_dt0.2
    python benchmarks/throughput.py --quick
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import throughput as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
