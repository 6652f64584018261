"""Station geometry derived from a configuration: where robots wait their turn at each dock.

Pure geometry, shared by the configuration's validation (can every robot that may queue at a
station find a place?) and the task cycle (which slot does each waiting robot drive to?).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

MAX_ROWS = 100
WALL_CLEARANCE_M = 0.05  # a dock or waiting slot keeps a robot this far off the walls
# Rows of a line stand this many slot spacings apart: every second lane is an aisle, so a robot
# waiting in an inner row, or leaving the dock, always has a free lane to drive along.
ROW_PITCH = 2


def waiting_rows(
    dock: Sequence[float],
    direction: Sequence[float],
    other_docks: Sequence[Sequence[float]],
    width: float,
    height: float,
    radius: float,
    offset: float,
    spacing: float,
    count: int,
) -> list[np.ndarray]:
    """Up to `count` waiting positions for one station, as rows in the order robots fill them.

    The first row runs from the dock along `direction` (first slot `offset` from the dock, then
    every `spacing`); where it would leave the arena or come within reach of another station, a new
    row starts `ROW_PITCH` spacings further toward the arena's interior, leaving an aisle between
    rows. Rows snake: odd rows are filled from their far end back toward the dock, so the line is
    one path and moving up is always one slot, never the width of the arena. A slot is kept only if
    it is at least `spacing` nearer its own dock than any other dock, so waiting robots of
    different stations stay at least one spacing apart. Fewer than `count` slots if no more fit.
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
    # A row leaves the arena within this many slots (checked below, all at once per row).
    reach = max(float(np.hypot(*along)) * spacing, 1e-12)
    longest = int(math.hypot(width, height) / reach) + 2

    def fitting(row: int, cap: int) -> int:
        """How many slots of `row` fit, from its start (at most `cap`): the same points and tests
        as one slot at a time, in growing blocks of slots (rows are mostly short)."""
        shift = across * row * ROW_PITCH * spacing
        start, block = 0, 16
        while start < cap:
            k = np.arange(start, min(start + block, cap))
            p = base + along * (offset + k * spacing)[:, None] + shift
            ok = np.all(p >= lo, axis=1) & np.all(p <= hi, axis=1)
            if others.size:
                own = np.hypot(p[:, 0] - base[0], p[:, 1] - base[1])
                gaps = np.hypot(
                    others[None, :, 0] - p[:, None, 0], others[None, :, 1] - p[:, None, 1]
                )
                ok &= np.all(gaps >= (own + spacing)[:, None], axis=1)
            if not ok.all():
                return start + int(np.argmin(ok))
            start, block = start + len(k), 2 * block
        return cap

    rows: list[np.ndarray] = []
    left = count
    for row in range(MAX_ROWS):
        if left <= 0:
            break
        # the first row is cut at `count`; a snaking row needs its whole length to know where it
        # starts
        fit = fitting(row, left if row == 0 else longest)
        if fit == 0:
            break
        k = np.arange(fit)
        line = base + along * (offset + k * spacing)[:, None] + across * row * ROW_PITCH * spacing
        if row % 2 == 1:
            line = line[::-1]
        rows.append(np.array(line[:left], dtype=float).reshape(-1, 2))
        left -= len(rows[-1])
    return rows


def stack_rows(rows: Sequence[np.ndarray]) -> np.ndarray:
    """The slots of `waiting_rows` as one (k, 2) array, in the order the line fills them."""
    return np.vstack(rows) if rows else np.zeros((0, 2))
