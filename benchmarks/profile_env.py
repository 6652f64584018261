"""A 2-hour random-choice run of `dahl2004` through the PettingZoo env, to profile.

    pip install py-spy
    py-spy record --native -r 400 -o profile.svg -- python benchmarks/profile_env.py --hours 20
    py-spy record --native -o profile96.svg -- python benchmarks/profile_env.py --robots 96 --hours 1

The run is the one `benchmarks/throughput.py` times (`profile_run` here).
What the profiles taught (in `results/profile/`): before issue 5 reading each body's position and
setting each body's velocity through pymunk's Python attributes cost more than the physics step;
batched I/O over numpy buffers and one fused post-step check removed most of that. Before issue 24
the rest of the tick's Python (pymunk's `Space.step` wrapper, unboxing the controller's arguments
twice per tick, the batch calls) still took about three quarters of the CPU time; the tick now
runs in compiled code. Before issue 38's compiled task rules, the task rules in Python at events
(about six returns from the compiled loop per task) took about a quarter of the CPU time at 6
robots; they now run inside the loop, and what is left is Chipmunk's step, the controller, and
the env's Python per step. The one-off cost is numba's start-up (about 1 s per process, cached code included).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from arena_runs import TEAM_SIZES, random_choice_run, team_config
from tavc_agents.experiments.study import parse_settings


@dataclass(frozen=True, kw_only=True)
class ProfileSettings:
    """The run to profile (its command line)."""

    hours: float = 2.0
    """simulated hours"""
    robots: int = 6
    """team size, among 6, 24, 96, 384"""
    seed: int = 0
    """env seed (the choices come from a Generator seeded [seed, 1])"""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.hours) and self.hours > 0):
            raise ValueError(f"hours = {self.hours!r} is invalid; allowed: > 0")
        if self.robots not in TEAM_SIZES:
            raise ValueError(
                f"robots = {self.robots!r} is invalid; allowed: one of {list(TEAM_SIZES)}"
            )


def profile_run(settings: ProfileSettings) -> str:
    """One random-choice run of the env, as `run_size` times it; returns what it did."""
    found = random_choice_run(team_config(settings.robots), settings.seed, settings.hours * 3600.0)
    return (
        f"{found['sim_s'] / 3600:g} simulated h, {found['ticks']:.0f} ticks, "
        f"{found['decisions']:.0f} decisions in {found['cpu_s']:.1f} CPU s "
        f"({found['sim_s'] / found['cpu_s']:,.0f} simulated s per CPU s)"
    )


def main(argv: Sequence[str] | None = None) -> int:
    settings = parse_settings(ProfileSettings, argv, __doc__ or "")
    print(profile_run(settings))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
