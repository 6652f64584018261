"""Station geometry derived from a configuration: where robots wait their turn at each dock.

Pure geometry, shared by the configuration's validation (can every robot that may queue at a
station find a place?) and the task cycle (which slot does each waiting robot drive to?).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

MAX_ROWS = 100
WALL_CLEARANCE_M = 0.05  # a dock or waiting slot keeps a robot this far off the walls


def waiting_slots(
    dock: Sequence[float],
    direction: Sequence[float],
    other_docks: Sequence[Sequence[float]],
    width: float,
    height: float,
    radius: float,
    offset: float,
    spacing: float,
    count: int,
) -> np.ndarray:
    """Up to `count` waiting positions for one station, nearest the dock first.

    The first row runs from the dock along `direction` (first slot `offset` from the dock, then
    every `spacing`); where it would leave the arena or come within reach of another station, a new
    row starts one spacing further toward the arena's interior. A slot is kept only if it is at
    least `spacing` nearer its own dock than any other dock, so waiting robots of different
    stations stay at least one spacing apart. Returns fewer than `count` slots if no more fit.
    """
    margin = radius + WALL_CLEARANCE_M
    lo = np.array([margin, margin])
    hi = np.array([width - margin, height - margin])
    base = np.asarray(dock, dtype=float)
    along = np.asarray(direction, dtype=float)
    across = np.array([-along[1], along[0]])
    if np.dot(np.array([width / 2, height / 2]) - base, across) < 0:
        across = -across
    others = np.asarray(other_docks, dtype=float).reshape(-1, 2)

    def fits(p: np.ndarray) -> bool:
        if np.any(p < lo) or np.any(p > hi):
            return False
        if others.size == 0:
            return True
        own = float(np.hypot(*(p - base)))
        return bool(np.all(np.hypot(*(others - p).T) >= own + spacing))

    slots: list[np.ndarray] = []
    for row in range(MAX_ROWS):
        k = 0
        while len(slots) < count:
            p = base + along * (offset + k * spacing) + across * row * spacing
            if not fits(p):
                break
            slots.append(p)
            k += 1
        if k == 0 or len(slots) >= count:
            break
    return np.array(slots, dtype=float).reshape(-1, 2)
