"""A 2-hour random-choice run of `dahl2004` through the PettingZoo env, to profile.

    pip install pyinstrument
    pyinstrument -i 0.0002 benchmarks/profile_env.py
    pyinstrument -i 0.0002 benchmarks/profile_env.py --robots 96 --hours 0.25

The run is the one `benchmarks/throughput.py` times (`tavc_agents.studies.throughput.profile_run`).
What the profiles taught (before / after issue 5, in `results/profile/`): the physics step was a
small part of a tick; reading each body's position and setting each body's velocity through
pymunk's Python attributes cost more than the step itself, followed by the controller call's
argument conversions. Batched I/O over numpy buffers and one fused post-step check removed most
of that. The one-off cost left is numba's start-up (about 1 s per process, cached code included).
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.studies import throughput as study
from tavc_agents.studies.common import parse_settings


def main(argv: Sequence[str] | None = None) -> int:
    settings = parse_settings(study.ProfileSettings, argv, __doc__ or "")
    print(study.profile_run(settings))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
