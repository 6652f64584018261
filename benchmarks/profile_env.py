"""A 2-hour random-choice run of `dahl2004` through the PettingZoo env, to profile.

    pip install py-spy
    py-spy record --native -r 400 -o profile.svg -- python benchmarks/profile_env.py --hours 20
    py-spy record --native -o profile96.svg -- python benchmarks/profile_env.py --robots 96 --hours 1

The run is the one `benchmarks/throughput.py` times (`tavc_agents.studies.throughput.profile_run`).
What the profiles taught (in `results/profile/`): before issue 5 reading each body's position and
setting each body's velocity through pymunk's Python attributes cost more than the physics step;
batched I/O over numpy buffers and one fused post-step check removed most of that. Before issue 24
the rest of the tick's Python (pymunk's `Space.step` wrapper, unboxing the controller's arguments
twice per tick, the batch calls) still took about three quarters of the CPU time; the tick now
runs in compiled code, and what is left is Chipmunk's step, the controller, and the task rules
at events. The one-off cost is numba's start-up (about 1 s per process, cached code included).
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import parse_settings
from tavc_agents.studies import throughput as study


def main(argv: Sequence[str] | None = None) -> int:
    settings = parse_settings(study.ProfileSettings, argv, __doc__ or "")
    print(study.profile_run(settings))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
