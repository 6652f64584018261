"""Synthetic interference tables with a chosen crowding elasticity e, for the model twin.

A family of arenas for the paper's team (3 fast robots at 0.30 m/s, 3 slow at 0.20 m/s, two
circuits alike but for their values): a robot of class c with f fast and s slow robots on its
circuit (n = f + s, itself included) takes on average

    T_c(f, s) = H + b_c(f, s) k(n) + W (k(n) - 1),    k(n) = 1 + step * max(0, n - 3)

* b_c: the robot's free task time, 60 s fast and 90 s slow (the speed ratio 0.30 / 0.20);
* k(n): crowding. A circuit carries three robots without interference (a station that serves
  three at once); each robot beyond the third stretches every robot's travel by `step` (0.5) of
  its free time. t(4) / t(3) = 1.5 with H = W = 0: the knee that makes 3 + 3 the homogeneous
  equilibrium of circuits worth 2200 and 2000;
* H: a fixed handling time every robot spends alike, untouched by crowding. It dilutes the
  crowding of the slow robots (whose longer travel is stretched more) less than the fast ones':
  e < 1, down to b_fast / b_slow = 2/3 as H grows;
* W: an additive wait, the same for every robot, that grows with the crowd. It is a larger
  share of a shorter task: e > 1, but only to about 1.17 (with large W every task is mostly wait
  and e returns to 1);
* pace p in [0, 1]: a fast robot sharing its circuit with a slow one drives at the slow robot's
  pace for a fraction p of its travel, b_fast(f, s >= 1) = b_fast + p (b_slow - b_fast). p = 1 is
  what every physical arena of the package measured (rho = T_slow(1, 1) / T_fast(1, 1) = 1, the
  fast robot held behind the slow one), and what gives them e of 1.1 to 3.4: here e reaches 2.04.

H = W = p = 0 is pure multiplicative crowding, e = 1. Cell standard deviations are `cv` (0.1) of
the means; the switch cost (1.13) is what `dahl2004`'s switch tasks cost under random allocation
in the physics (benchmarks/results/twin_audit/twin_audit.md: 1.133 [1.129, 1.137] of their cell).

`with_elasticity(e)` solves for H (e < 1) or p (or W, `above="wait"`) by bisection on
`elasticity_of` (circuit 0's tables), and refuses an e the family cannot reach: below about 0.744
the H it needs would flatten the knee under t(4) / t(3) = 1.1 (at a homogeneous team of the mean
speed 0.25 m/s, free time 72 s), above about 2.04 even p = 1 is not enough.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

import tavc_env
from tavc_agents.analysis.elasticity import ALONE, CROWDED, Tables, elasticity_of
from tavc_env.config import ArenaConfig
from tavc_env.twin import InterferenceTables, team_classes
from tavc_env.validation import is_number, require

KNEE_MIN = 2200.0 / 2000.0
"""t(4) / t(3) above the circuits' value ratio: a fourth robot earns less on the high-value
circuit than the third on the other, so 3 + 3 is the homogeneous equilibrium"""
CAPACITY = 3
"""robots a circuit carries without interference"""
_BISECTIONS = 200
_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Family:
    """One member of the family (see the module's docstring); times in seconds."""

    handling_s: float = 0.0
    """H, the fixed handling time every robot spends alike (e < 1)"""
    wait_s: float = 0.0
    """W, the additive wait equal for every robot, times k(n) - 1 (e > 1, up to about 1.17)"""
    pace: float = 0.0
    """p, the fraction of a fast robot's travel at the slow robots' pace in their company (e > 1)"""
    b_fast_s: float = 60.0
    """free task time of a fast robot"""
    b_slow_s: float = 90.0
    """free task time of a slow robot"""
    step: float = 0.5
    """k(n) = 1 + step * max(0, n - 3)"""
    cv: float = 0.1
    """every cell's standard deviation over its mean"""
    switch_cost: float = 1.13
    """factor on a task that starts on the other circuit (dahl2004's as paid, twin audit)"""

    def __post_init__(self) -> None:
        for name in ("handling_s", "wait_s", "cv"):
            value = getattr(self, name)
            require(is_number(value) and value >= 0, name, value, "a finite number >= 0")
        for name in ("b_fast_s", "b_slow_s", "step", "switch_cost"):
            value = getattr(self, name)
            require(is_number(value) and value > 0, name, value, "a finite number > 0")
        require(
            is_number(self.pace) and 0 <= self.pace <= 1, "pace", self.pace, "a number in [0, 1]"
        )
        require(
            self.b_fast_s < self.b_slow_s,
            "b_fast_s",
            self.b_fast_s,
            f"a free task time shorter than b_slow_s = {self.b_slow_s!r} (fast robots are faster)",
        )

    def k(self, n: int) -> float:
        """The crowding factor of `n` robots on a circuit."""
        return 1.0 + self.step * max(0, n - CAPACITY)

    def _time(self, free_s: float, n: int) -> float:
        k = self.k(n)
        return self.handling_s + free_s * k + self.wait_s * (k - 1.0)

    def mean_s(self, robot_class: str, fast: int, slow: int) -> float:
        """T_c(f, s): the mean task time of a `robot_class` robot with `fast` fast and `slow` slow
        robots on its circuit (itself included)."""
        require(robot_class in ("fast", "slow"), "robot_class", robot_class, "'fast' or 'slow'")
        mine = fast if robot_class == "fast" else slow
        require(
            isinstance(fast, int) and isinstance(slow, int) and mine >= 1 and min(fast, slow) >= 0,
            "counts",
            (fast, slow),
            f"robots >= 0 of each class, at least one {robot_class} robot (the robot itself)",
        )
        if robot_class == "slow":
            free = self.b_slow_s
        else:
            free = self.b_fast_s + (self.pace * (self.b_slow_s - self.b_fast_s) if slow else 0.0)
        return self._time(free, fast + slow)

    def knee(self) -> float:
        """t(4) / t(3) of a homogeneous team of the mean speed (free time the harmonic mean of
        b_fast and b_slow: 72 s for 60 and 90), as the interference study measures it at
        0.25 m/s."""
        free = 2.0 * self.b_fast_s * self.b_slow_s / (self.b_fast_s + self.b_slow_s)
        return self._time(free, 4) / self._time(free, 3)

    def elasticity_tables(self) -> Tables:
        """T_fast and T_slow on one circuit in the cells e uses."""
        cells = (ALONE["fast"], ALONE["slow"], *CROWDED)
        return Tables(
            fast={(f, s): self.mean_s("fast", f, s) for f, s in cells if f},
            slow={(f, s): self.mean_s("slow", f, s) for f, s in cells if s},
        )

    def elasticity(self) -> float:
        """e of these tables (`tavc_agents.analysis.elasticity.elasticity_of`)."""
        return elasticity_of(self.elasticity_tables())

    def describe(self) -> str:
        return (
            f"H = {self.handling_s:.4g} s, W = {self.wait_s:.4g} s, pace {self.pace:.4g}, "
            f"b = {self.b_fast_s:g} / {self.b_slow_s:g} s, k(n) = 1 + {self.step:g} "
            f"max(0, n - {CAPACITY}), cv {self.cv:g}, switch cost {self.switch_cost:g}"
        )

    def tables(self, config: ArenaConfig | None = None) -> InterferenceTables:
        """The twin's tables for `config` (default: `dahl2004`, the paper's team and circuits):
        every circuit alike, each cell's mean `mean_s` and standard deviation `cv` of it."""
        config = tavc_env.make_config("dahl2004") if config is None else config
        classes, _ = team_classes(config)
        require(
            sorted(classes) == ["fast", "slow"],
            "config",
            f"speed classes {list(classes)}",
            "an arena whose robots are of the classes 'fast' and 'slow'",
        )
        i_fast, i_slow = classes.index("fast"), classes.index("slow")

        def mean(_: int, counts: tuple[int, ...], cls: str) -> float:
            return self.mean_s(cls, counts[i_fast], counts[i_slow])

        return InterferenceTables.from_function(
            config,
            mean,
            lambda k, counts, cls: self.cv * mean(k, counts, cls),
            self.switch_cost,
            source=f"synthetic, e = {self.elasticity():.4f}: {self.describe()}",
        )


def max_handling_s(base: Family) -> float:
    """The largest H that keeps the knee at `KNEE_MIN` (the knee falls linearly as H grows)."""
    zero = replace(base, handling_s=0.0)
    free = 2.0 * base.b_fast_s * base.b_slow_s / (base.b_fast_s + base.b_slow_s)
    t3, t4 = zero._time(free, 3), zero._time(free, 4)
    # (H + t4) / (H + t3) = KNEE_MIN
    return max(0.0, (t4 - KNEE_MIN * t3) / (KNEE_MIN - 1.0))


def _peak_wait_s(base: Family) -> float:
    """The W of the largest e the wait reaches (e rises with W, then falls back towards 1)."""
    grid = np.geomspace(1e-3, 1e5, 801) * base.b_slow_s
    e = [replace(base, wait_s=float(w)).elasticity() for w in grid]
    return float(grid[int(np.argmax(e))])


def reach(base: Family = Family(), above: Literal["pace", "wait"] = "pace") -> tuple[float, float]:
    """The lowest and highest e `with_elasticity` reaches from `base`'s other parameters."""
    low = replace(base, handling_s=max_handling_s(base), wait_s=0.0, pace=0.0).elasticity()
    if above == "pace":
        high = replace(base, handling_s=0.0, wait_s=0.0, pace=1.0).elasticity()
    else:
        high = replace(base, handling_s=0.0, wait_s=_peak_wait_s(base), pace=0.0).elasticity()
    return low, high


def with_elasticity(
    e: float, base: Family = Family(), above: Literal["pace", "wait"] = "pace"
) -> Family:
    """`base` with H (e < 1), the pace p or the wait W (e > 1, by `above`) set so that its
    elasticity is `e` (to 1e-9), the other two at 0. A ValueError names an e the family cannot
    reach from `base` (see `reach`)."""
    require(above in ("pace", "wait"), "above", above, "'pace' or 'wait'")
    require(is_number(e) and e > 0, "e", e, "a finite elasticity > 0")
    plain = replace(base, handling_s=0.0, wait_s=0.0, pace=0.0)
    if e == 1.0:
        return plain
    if e < 1.0:
        name, hi = "handling_s", max_handling_s(base)
    elif above == "pace":
        name, hi = "pace", 1.0
    else:
        name, hi = "wait_s", _peak_wait_s(base)
    low_e, high_e = reach(base, above)
    if not (low_e <= e <= high_e) or hi == 0.0:
        raise ValueError(
            f"e = {e!r} is invalid; allowed: an elasticity in [{low_e:.4f}, {high_e:.4f}], what "
            f"H (e < 1, kept at t(4) / t(3) >= {KNEE_MIN:g}) and the "
            f"{'pace p <= 1' if above == 'pace' else 'additive wait W'} (e > 1) reach from "
            f"{base.describe()}"
        )

    def gap(x: float) -> float:
        return replace(plain, **{name: x}).elasticity() - e

    lo, lo_gap = 0.0, gap(0.0)
    for _ in range(_BISECTIONS):  # e moves monotonically with x on [0, hi]
        mid = (lo + hi) / 2
        mid_gap = gap(mid)
        if (mid_gap < 0) == (lo_gap < 0):
            lo, lo_gap = mid, mid_gap
        else:
            hi = mid
        if hi - lo <= _TOLERANCE * max(1.0, hi):
            break
    best = min((lo, hi), key=lambda x: abs(gap(x)))
    found = replace(plain, **{name: best})
    if not math.isclose(found.elasticity(), e, abs_tol=1e-9):
        raise ValueError(f"e = {e!r} is invalid: no {name} gives it to 1e-9 (e is flat there)")
    return found
