"""Throughput of the arena at 6, 24, 96 and 384 robots, next to the bare-physics floor.

For each team size (`dahl2004` for 6 robots; `tavc_env.scaled_config(n_circuits, 3)` for 24, 96
and 384: 8, 32 and 128 lanes of three robots), in a fresh process of its own (so its peak memory
is its own), one core, every robot that must decide picking a circuit uniformly at random (seeded):

* `env`: the PettingZoo parallel env, event-driven stepping: simulated seconds, physics ticks and
  decisions per wall second;
* `floor`: the bare-physics floor in the same process: the package's `World` (same space, walls,
  bodies, solver settings) placed as at reset, each robot's velocity set once to its top speed in
  a random direction, then `space.step(dt)` in a loop, as many ticks as the env run made;
* `floor_each_tick`: the same with every velocity set again every tick (the least an engine with a
  controller must do).

The measurements of one size alternate (env, floors, env, floors, ...) `--repeats` times so load
hits them alike; reported are the means, the best repeat, the ratio env / floor (ticks per second,
paired by repeat), and the peak resident memory of the size's process. Goals (issue 5): 6 robots at
least 15 000x real time and 30 % of the floor; 96 robots at least 1 500x. Writes
`throughput.{csv,md,json}` into a new run folder under runs/ (git ignores it), `--out`, or with
`--update-reference` benchmarks/results/. The study is `tavc_agents.studies.throughput`.

    python benchmarks/throughput.py                # ~2 min
    python benchmarks/throughput.py --dt 0.2 --sizes 6 96 --out benchmarks/results/throughput_dt0.2
    python benchmarks/throughput.py --quick
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.studies import throughput as study
from tavc_agents.studies.common import run_study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
