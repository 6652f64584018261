"""The robots' low-level controller: drive to a target point, avoid walls and other robots.

Behaviour-based and reactive, like the paper's Pioneers in an open room. Each robot is a unicycle:
it turns at a bounded rate and drives forward along its heading. Three behaviours are blended:

* *go to target*: head for the target point, slowing down over the last metre;
* *avoid*: a robot ahead in the way (closer than the target, inside the corridor the robot sweeps)
  deflects the desired heading sideways, away from it, and robots dead ahead are passed on the
  right; so a faster robot overtakes a slower one where there is room, and robots meeting head-on
  pass each other;
* *keep apart*: robots closer than a small margin push away from each other and from walls.

Speed is capped by the free distance along the current heading (a robot brakes behind a robot it
cannot yet pass) and by the heading error (it turns on the spot when the target is behind it).

An optional *clearance governor* (`ArenaConfig.clearance_governor_m`, off by default) scales the
speed by min(1, clearance / governor), where the clearance is the free space between the robot's
body and the nearest other robot in its front half-plane within sensing range (what a laser
scanner's 180-degree field sees). This is how the laser-based obstacle-avoidance drivers of
Pioneer robots slow down in a crowd: every robot loses the same *fraction* of its own top speed
at a given clearance, whatever that top speed is, so crowding in travel is multiplicative.

*Overtaking* (`ArenaConfig.overtaking`, off by default) changes two things, as a laser-based
avoidance that passes slower traffic does: the governor measures the clearance only to robots in
the robot's own path (ahead, inside the corridor its body sweeps), not to a robot it is passing
alongside; and a robot dead ahead is passed on the side with room (the right unless the wall
leaves less room there than on the left). The robot then returns to its line by the pull of its
target. Every robot is treated alike; only its top speed differs.

The per-tick loop over robot pairs is one function, compiled by numba (the physics loop calls it
every 0.1 s of simulated time, so interpreted Python would dominate the run time); the compiled
tick at the end of this file (`run_ticks`) calls it with the physics step.
"""

from __future__ import annotations

import ctypes
import math
import os as _os
import warnings as _warnings
from collections.abc import Callable
from typing import Any, Literal, NamedTuple

import numpy as np
from llvmlite import ir
from numba import njit as _njit
from numba import types
from numba.core import config as _numba_config
from numba.extending import intrinsic
from numba.np.random._constants import fi_double as _ZIG_F
from numba.np.random._constants import ki_double as _ZIG_K
from numba.np.random._constants import wi_double as _ZIG_W
from numba.np.random._constants import ziggurat_nor_inv_r as _ZIG_INV_R
from numba.np.random._constants import ziggurat_nor_r as _ZIG_R

from tavc_env.config import ArenaConfig

_cache_warned: list[str] = []


def compiled(
    fn: Callable[..., Any], inline: bool = False, allocates: bool = False
) -> Callable[..., Any]:
    """numba's compiled `fn`, cached on disk; where no cache folder can be written (a
    read-only install run by another user), compiled at every start, with one warning.
    `inline`: compiled into each compiled caller rather than called (a small function called
    per robot pair, where the call itself costs more than its arithmetic).
    `allocates`: `fn` creates arrays, so it needs numba's reference counting; every other
    function only reads and writes the arrays its caller owns, and counting references to them
    (an atomic add per array argument, per inlined call) cost a third of the tick loop."""
    how: Literal["always", "never"] = "always" if inline else "never"
    options: dict[str, Any] = {"fastmath": False, "nogil": True, "inline": how, "_nrt": allocates}
    try:
        return _njit(cache=True, **options)(fn)
    except RuntimeError as error:  # numba: "cannot cache function ...: no locator available"
        if "no locator" not in str(error):
            raise
    if not _cache_warned:
        folders = [_os.path.join(_os.path.dirname(fn.__code__.co_filename), "__pycache__")]
        user_folder = getattr(_numba_config, "CACHE_DIR", "")  # NUMBA_CACHE_DIR
        if user_folder:
            folders.insert(0, user_folder)
        _cache_warned.append(folders[0])
        _warnings.warn(
            f"numba cannot write its cache (tried {' and '.join(folders)} and the user's "
            "cache folder): the robots' controller is compiled anew at every start (a few "
            "seconds); set NUMBA_CACHE_DIR to a writable folder to cache it",
            RuntimeWarning,
            stacklevel=2,
        )
    return _njit(cache=False, **options)(fn)


STEER_GAIN = 1.5  # sideways deflection per unit of obstacle weight
CORRIDOR_MARGIN_M = 0.15  # extra width beyond two radii that counts as "in the way"
KEEP_APART_MARGIN_M = 0.08
BRAKE_DISTANCE_M = 0.3  # free distance below which a robot slows linearly to a stop
BRAKE_GAP_M = 0.03
APPROACH_TIME_S = 1.0  # speed near the target is capped at distance / this time
ARRIVED_M = 0.03  # closer than this to its target a robot holds still
WALL_RANGE_M = 0.25
# Escape behaviour (see Simulation): a robot that has not moved STUCK_RADIUS_M in STUCK_PATIENCE_S
# while away from its target drives ESCAPE_DISTANCE_M away from its neighbours for up to
# ESCAPE_TIME_S. Reactive controllers can knot in dense crowds; this is the behaviour-based cure.
STUCK_RADIUS_M = 0.15
STUCK_PATIENCE_S = 30.0
ESCAPE_DISTANCE_M = 1.0
ESCAPE_TIME_S = 4.0


def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


_clip_c = compiled(_clip, inline=True)


def _wrap(x: float) -> float:
    """`(x + pi) % (2 pi) - pi`, bit for bit: where `x + pi` already lies in [0, 2 pi) the modulo
    returns it unchanged, so it is skipped (a float modulo is a library call, the most common
    one in the controller)."""
    t = x + math.pi
    if 0.0 <= t < 2.0 * math.pi:
        return t - math.pi
    return t % (2.0 * math.pi) - math.pi


_wrap_c = compiled(_wrap, inline=True)


def _wall_room(x: float, y: float, nx: float, ny: float, width: float, height: float) -> float:
    """How far from (x, y) along the unit vector (nx, ny) the nearest wall is."""
    room = math.inf
    if nx > 0.0:
        room = (width - x) / nx
    elif nx < 0.0:
        room = x / -nx
    if ny > 0.0:
        room = min(room, (height - y) / ny)
    elif ny < 0.0:
        room = min(room, y / -ny)
    return room


_wall_room_c = compiled(_wall_room, inline=True)


def _steer_one(
    i: int,
    pos: np.ndarray,
    heading: np.ndarray,
    target: np.ndarray,
    moving: np.ndarray,
    top_speed: np.ndarray,
    present: np.ndarray,
    radius: float,
    sensing: float,
    governor: float,
    overtaking: bool,
    turn_step: float,
    width: float,
    height: float,
    others: np.ndarray,
    n_others: int,
    out_velocity: np.ndarray,
    out_heading: np.ndarray,
) -> None:
    """Robot i's command, considering the robots `others[:n_others]` (in increasing index order,
    so sums come out the same whichever way they were found)."""
    corridor = 2.0 * radius + CORRIDOR_MARGIN_M
    near = 2.0 * radius + KEEP_APART_MARGIN_M
    contact = 2.0 * radius
    pass_room = radius + contact + CORRIDOR_MARGIN_M  # beside a robot's centre, to pass it
    wall_lo = radius + WALL_RANGE_M
    px = pos[i, 0]
    py = pos[i, 1]
    gx = target[i, 0] - px
    gy = target[i, 1] - py
    gdist = math.sqrt(gx * gx + gy * gy)
    out_heading[i] = heading[i]
    out_velocity[i, 0] = 0.0
    out_velocity[i, 1] = 0.0
    if not (moving[i] and present[i] and gdist > ARRIVED_M):
        return
    ux = gx / gdist
    uy = gy / gdist
    steer = 0.0
    push_x = 0.0
    push_y = 0.0
    # beyond both the sensing range and `near` a robot changes nothing here: such pairs are
    # skipped on their squared distance, whose square root would be at least `reach` (a bound
    # above both, so the test can only skip pairs the exact test would skip)
    reach = max(sensing, near) * (1.0 + 1e-9)
    reach2 = reach * reach
    for k in range(n_others):
        j = others[k]
        if j == i or not present[j]:
            continue
        dx = pos[j, 0] - px
        dy = pos[j, 1] - py
        d2 = dx * dx + dy * dy
        if d2 >= reach2:
            continue
        dist = math.sqrt(d2)
        ahead = dx * ux + dy * uy
        lateral = ux * dy - uy * dx  # > 0: the other robot is on the left
        if ahead > 0.0 and abs(lateral) < corridor and dist < sensing and dist < gdist:
            w = _clip_c((sensing - dist) / (sensing - contact), 0.0, 1.0)
            w *= 1.0 - abs(lateral) / corridor
            left = lateral < 0.0  # away from it; dead ahead: to the right
            if overtaking and abs(lateral) < radius:
                # nearly dead ahead: pass on the other side if the wall leaves too little room
                # beside it on this one and more on that one
                room_left = _wall_room_c(pos[j, 0], pos[j, 1], -uy, ux, width, height)
                room_right = _wall_room_c(pos[j, 0], pos[j, 1], uy, -ux, width, height)
                room = room_left if left else room_right
                other = room_right if left else room_left
                if room < pass_room and other > room:
                    left = not left
            steer += -w if left else w
        if dist < near:
            overlap = min((near - dist) / KEEP_APART_MARGIN_M, 2.0)
            inv = overlap / max(dist, 1e-9)
            push_x -= inv * dx
            push_y -= inv * dy
    steer = _clip_c(steer, -2.0, 2.0)
    # +steer turns toward the right-hand normal (uy, -ux) of the goal direction.
    want_x = ux + STEER_GAIN * steer * uy + push_x
    want_y = uy - STEER_GAIN * steer * ux + push_y
    want_x += _clip_c((wall_lo - px) / WALL_RANGE_M, 0.0, 1.0)
    want_x -= _clip_c((px - (width - wall_lo)) / WALL_RANGE_M, 0.0, 1.0)
    want_y += _clip_c((wall_lo - py) / WALL_RANGE_M, 0.0, 1.0)
    want_y -= _clip_c((py - (height - wall_lo)) / WALL_RANGE_M, 0.0, 1.0)

    phi = math.atan2(want_y, want_x)
    err = _wrap_c(phi - heading[i])
    turn = _clip_c(err, -turn_step, turn_step)
    h = _wrap_c(heading[i] + turn)
    # cos(err - turn), clipped at 0; within the turn step err - turn is 0.0 and its cosine 1.0
    # exactly, without the library call
    c = 1.0 if turn == err else max(math.cos(err - turn), 0.0)
    speed = min(top_speed[i] * c * c, gdist / APPROACH_TIME_S)

    hx = math.cos(h)
    hy = math.sin(h)
    free = math.inf
    clearance = math.inf
    for k in range(n_others):
        j = others[k]
        if j == i or not present[j]:
            continue
        dx = pos[j, 0] - px
        dy = pos[j, 1] - py
        along = dx * hx + dy * hy
        across = abs(hx * dy - hy * dx)
        if along > 0.0 and across < contact:
            free = min(free, along - math.sqrt(contact * contact - across * across))
        if governor > 0.0 and along > 0.0 and (not overtaking or across < corridor):
            clearance = min(clearance, math.sqrt(dx * dx + dy * dy) - contact)
    speed *= _clip_c((free - BRAKE_GAP_M) / BRAKE_DISTANCE_M, 0.0, 1.0)
    if governor > 0.0 and clearance < governor:
        speed *= _clip_c(clearance / governor, 0.0, 1.0)
    out_heading[i] = h
    out_velocity[i, 0] = speed * hx
    out_velocity[i, 1] = speed * hy


_steer_one_c = compiled(_steer_one, inline=True)


def _steer_all(
    pos: np.ndarray,
    heading: np.ndarray,
    target: np.ndarray,
    moving: np.ndarray,
    top_speed: np.ndarray,
    present: np.ndarray,
    radius: float,
    sensing: float,
    governor: float,
    overtaking: bool,
    turn_step: float,
    width: float,
    height: float,
    out_velocity: np.ndarray,
    out_heading: np.ndarray,
) -> None:
    """Every robot's command, each considering every other robot (O(n^2); best for small teams)."""
    _steer_pairs_c(
        pos, heading, target, moving, top_speed, present, radius, sensing, governor, overtaking,
        turn_step, width, height, out_velocity, out_heading, np.arange(pos.shape[0]),
    )  # fmt: skip


def _steer_pairs(
    pos: np.ndarray,
    heading: np.ndarray,
    target: np.ndarray,
    moving: np.ndarray,
    top_speed: np.ndarray,
    present: np.ndarray,
    radius: float,
    sensing: float,
    governor: float,
    overtaking: bool,
    turn_step: float,
    width: float,
    height: float,
    out_velocity: np.ndarray,
    out_heading: np.ndarray,
    everyone: np.ndarray,
) -> None:
    """`steer_all` with `everyone` = arange(n) given (the compiled tick allocates it once per
    call, not once per tick)."""
    n = pos.shape[0]
    for i in range(n):
        _steer_one_c(
            i,
            pos,
            heading,
            target,
            moving,
            top_speed,
            present,
            radius,
            sensing,
            governor,
            overtaking,
            turn_step,
            width,
            height,
            everyone,
            n,
            out_velocity,
            out_heading,
        )


_steer_pairs_c = compiled(_steer_pairs)


def neighbour_cell_m(radius: float, sensing: float) -> float:
    """The grid cell size beyond which no robot can change another's command: the sensing range
    (steering, keeping apart) or the distance at which a robot ahead starts to brake one."""
    contact = 2.0 * radius
    brake = math.hypot(BRAKE_GAP_M + BRAKE_DISTANCE_M + contact, contact)
    return max(sensing, brake) * (1.0 + 1e-9)


def _first_at_least(keys: np.ndarray, value: int) -> int:
    """The first index of sorted `keys` whose key is >= `value` (len(keys) if none)."""
    lo = 0
    hi = keys.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


_first_at_least_c = compiled(_first_at_least)


def _steer_all_grid(
    pos: np.ndarray,
    heading: np.ndarray,
    target: np.ndarray,
    moving: np.ndarray,
    top_speed: np.ndarray,
    present: np.ndarray,
    radius: float,
    sensing: float,
    governor: float,
    overtaking: bool,
    turn_step: float,
    width: float,
    height: float,
    out_velocity: np.ndarray,
    out_heading: np.ndarray,
    cell: float,
) -> None:
    """`steer_all` for large teams: robots are binned into square cells of side `cell`
    (`neighbour_cell_m`), and each robot considers only those in the 3 x 3 cells around it, in
    increasing index order, so the commands are exactly those of `steer_all` in O(n log n) time.

    The grid is sparse: the robots on the floor are sorted by cell (row-major cell number, then
    index) and each row of three cells is found by binary search, so memory and time do not grow
    with the arena's area (a dense table of every cell died with MemoryError in a 1e5 m arena).
    (`steer_grid_into` with scratch arrays of its own; the compiled tick keeps them.)"""
    n = pos.shape[0]
    _steer_grid_into_c(
        pos, heading, target, moving, top_speed, present, radius, sensing, governor, overtaking,
        turn_step, width, height, out_velocity, out_heading, cell, np.zeros(n, np.int64),
        np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64),
        np.zeros(n, np.int64), np.zeros(n, np.int64), np.full(1, -1, np.int64),
    )  # fmt: skip


def grid_scratch(n: int) -> tuple[np.ndarray, ...]:
    """The neighbour grid's working arrays for n robots: cell x, cell y, cell number, the robots
    on the floor sorted by (cell number, index), their cell numbers, a robot's neighbours, and
    [how many robots `order` holds, -1: none yet]; then the neighbour lists' (`steer_near_into`):
    every robot's candidates one after another, where each robot's start, the positions and
    presence at their making, and [whether they are valid: 1, or not yet: -1]."""
    return (
        np.zeros(n, np.int64),
        np.zeros(n, np.int64),
        np.zeros(n, np.int64),
        np.zeros(n, np.int64),
        np.zeros(n, np.int64),
        np.zeros(n, np.int64),
        np.full(1, -1, np.int64),
        np.zeros(n * min(n, NEAR_PER_ROBOT), np.int64),
        np.zeros(n + 1, np.int64),
        np.zeros((n, 2)),
        np.zeros(n, np.bool_),
        np.full(1, -1, np.int64),
    )


NEAR_PER_ROBOT = 64  # room in the neighbour lists per robot, on average (beyond: the grid)
NEAR_SKIN_M = 1.0  # the lists reach this much beyond a cell; made anew when a robot moved half


def _bin(
    pos: np.ndarray,
    present: np.ndarray,
    cell: float,
    width: float,
    height: float,
    cx: np.ndarray,
    cy: np.ndarray,
    key: np.ndarray,
    order: np.ndarray,
    keys: np.ndarray,
    held: np.ndarray,
) -> tuple[int, int, int]:
    """Bin the robots into square cells of side `cell`: each robot's cell (cx, cy, key), and the
    robots on the floor sorted by (cell number, index) into `order` (their keys into `keys`).
    `order` is sorted again from what it held by insertion, which costs O(n) while few robots
    change cells, where a fresh sort cost O(n log n) and its allocations every call. The sorted
    order of distinct (cell, index) pairs is unique, so it is the one a stable sort by cell
    number of the robots in index order gives, whatever the scratch held. Returns the grid's
    columns and rows and how many robots are on the floor."""
    n = pos.shape[0]
    nx = max(int(width / cell) + 1, 1)
    ny = max(int(height / cell) + 1, 1)
    n_present = 0
    for i in range(n):
        cx[i] = min(max(int(pos[i, 0] / cell), 0), nx - 1)
        cy[i] = min(max(int(pos[i, 1] / cell), 0), ny - 1)
        key[i] = cy[i] * nx + cx[i]
        if present[i]:
            n_present += 1
    valid = held[0] == n_present
    if valid:  # the same robots on the floor (distinct indices, all present, as many)
        for k in range(n_present):
            if not present[order[k]]:
                valid = False
                break
    if not valid:
        k = 0
        for i in range(n):
            if present[i]:
                order[k] = i
                k += 1
        held[0] = n_present
    for a in range(1, n_present):  # insertion sort by (cell number, index)
        v = order[a]
        kv = key[v]
        b = a - 1
        while b >= 0 and (key[order[b]] > kv or (key[order[b]] == kv and order[b] > v)):
            order[b + 1] = order[b]
            b -= 1
        order[b + 1] = v
    for k in range(n_present):
        keys[k] = key[order[k]]
    return nx, ny, n_present


_bin_c = compiled(_bin, inline=True)


def _gather(
    i: int,
    nx: int,
    ny: int,
    n_present: int,
    cx: np.ndarray,
    cy: np.ndarray,
    order: np.ndarray,
    keys: np.ndarray,
    others: np.ndarray,
) -> int:
    """Write into `others` the robots binned (`_bin`) in the 3 x 3 cells around robot i's, in
    increasing index order; return how many."""
    m = 0
    x0 = max(cx[i] - 1, 0)
    x1 = min(cx[i] + 1, nx - 1)
    y0 = max(cy[i] - 1, 0)
    y1 = min(cy[i] + 2, ny)
    items = order[:n_present]
    keys_in = keys[:n_present]
    for yy in range(y0, y1):
        # cells x0..x1 of row yy are the consecutive cell numbers row + x0 .. row + x1: one
        # search for the first, then the sorted keys in order up to the last
        k = _first_at_least_c(keys_in, yy * nx + x0)
        end = yy * nx + x1 + 1
        while k < n_present and keys_in[k] < end:
            others[m] = items[k]
            m += 1
            k += 1
    # the cells are visited row by row: merge them into increasing index order
    for a in range(1, m):
        v = others[a]
        b = a - 1
        while b >= 0 and others[b] > v:
            others[b + 1] = others[b]
            b -= 1
        others[b + 1] = v
    return m


_gather_c = compiled(_gather, inline=True)


def _steer_grid_into(
    pos: np.ndarray,
    heading: np.ndarray,
    target: np.ndarray,
    moving: np.ndarray,
    top_speed: np.ndarray,
    present: np.ndarray,
    radius: float,
    sensing: float,
    governor: float,
    overtaking: bool,
    turn_step: float,
    width: float,
    height: float,
    out_velocity: np.ndarray,
    out_heading: np.ndarray,
    cell: float,
    cx: np.ndarray,
    cy: np.ndarray,
    key: np.ndarray,
    order: np.ndarray,
    keys: np.ndarray,
    others: np.ndarray,
    held: np.ndarray,
) -> None:
    """`steer_all_grid` on scratch arrays (`grid_scratch`) kept from tick to tick (see `_bin`):
    the commands are those of `steer_all_grid` whatever the scratch held."""
    nx, ny, n_present = _bin_c(pos, present, cell, width, height, cx, cy, key, order, keys, held)
    for i in range(pos.shape[0]):
        m = 0
        if moving[i] and present[i]:  # (else it holds still and looks at nobody)
            m = _gather_c(i, nx, ny, n_present, cx, cy, order, keys, others)
        _steer_one_c(
            i, pos, heading, target, moving, top_speed, present, radius, sensing, governor,
            overtaking, turn_step, width, height, others, m, out_velocity, out_heading,
        )  # fmt: skip


_steer_grid_into_c = compiled(_steer_grid_into)
steer_grid_into = _steer_grid_into_c
steer_all_grid = compiled(_steer_all_grid, allocates=True)
GRID_MIN_ROBOTS = 16  # from this team size on the grid is faster than all pairs


def _steer_near_into(
    pos: np.ndarray,
    heading: np.ndarray,
    target: np.ndarray,
    moving: np.ndarray,
    top_speed: np.ndarray,
    present: np.ndarray,
    radius: float,
    sensing: float,
    governor: float,
    overtaking: bool,
    turn_step: float,
    width: float,
    height: float,
    out_velocity: np.ndarray,
    out_heading: np.ndarray,
    cell: float,
    cx: np.ndarray,
    cy: np.ndarray,
    key: np.ndarray,
    order: np.ndarray,
    keys: np.ndarray,
    others: np.ndarray,
    held: np.ndarray,
    near: np.ndarray,
    near_start: np.ndarray,
    near_anchor: np.ndarray,
    near_present: np.ndarray,
    near_held: np.ndarray,
) -> None:
    """`steer_grid_into` on neighbour lists kept over ticks: each robot's candidates are the
    robots in the 3 x 3 cells of side `cell + NEAR_SKIN_M` around it, made when no list is held,
    a robot left or entered the floor, or one moved more than (about) half the skin since. A
    pair within `cell` now was within `cell + NEAR_SKIN_M` then, so every robot that can change
    a command is a candidate, in increasing index order, and a candidate beyond `cell` changes
    nothing: the commands are exactly `steer_grid_into`'s. Where the lists would not fit in
    `near` (a crowd far denser than `NEAR_PER_ROBOT`), that tick is `steer_grid_into`'s."""
    n = pos.shape[0]
    fresh = near_held[0] < 0
    if not fresh:
        limit = 0.49 * NEAR_SKIN_M  # below half the skin, with room for rounding
        limit2 = limit * limit
        for i in range(n):
            if present[i] != near_present[i]:
                fresh = True
                break
            dx = pos[i, 0] - near_anchor[i, 0]
            dy = pos[i, 1] - near_anchor[i, 1]
            if present[i] and dx * dx + dy * dy > limit2:
                fresh = True
                break
    if fresh:
        big = cell + NEAR_SKIN_M
        nx, ny, n_present = _bin_c(pos, present, big, width, height, cx, cy, key, order, keys, held)
        total = 0
        near_held[0] = 1
        for i in range(n):
            near_start[i] = total
            near_anchor[i, 0] = pos[i, 0]
            near_anchor[i, 1] = pos[i, 1]
            near_present[i] = present[i]
            if present[i]:  # (moving or not: it may start moving before the next lists)
                m = _gather_c(i, nx, ny, n_present, cx, cy, order, keys, others)
                if total + m > near.shape[0]:
                    near_held[0] = -1
                    break
                for k in range(m):
                    near[total + k] = others[k]
                total += m
        near_start[n] = total
        if near_held[0] < 0:
            _steer_grid_into_c(
                pos, heading, target, moving, top_speed, present, radius, sensing, governor,
                overtaking, turn_step, width, height, out_velocity, out_heading, cell, cx, cy,
                key, order, keys, others, held,
            )  # fmt: skip
            return
    for i in range(n):
        first = near_start[i]
        m = near_start[i + 1] - first
        _steer_one_c(
            i, pos, heading, target, moving, top_speed, present, radius, sensing, governor,
            overtaking, turn_step, width, height, near[first:], m, out_velocity, out_heading,
        )  # fmt: skip


_steer_near_into_c = compiled(_steer_near_into)
steer_near_into = _steer_near_into_c
steer_all = compiled(_steer_all, allocates=True)


def _arrivals(pos: np.ndarray, target: np.ndarray, trigger: np.ndarray, out: np.ndarray) -> int:
    """Write into `out` the robots within their trigger distance of their target; return how many.
    A trigger <= 0 never fires."""
    k = 0
    for i in range(pos.shape[0]):
        if trigger[i] > 0.0:
            dx = target[i, 0] - pos[i, 0]
            dy = target[i, 1] - pos[i, 1]
            if dx * dx + dy * dy <= trigger[i] * trigger[i]:
                out[k] = i
                k += 1
    return k


_arrivals_c = compiled(_arrivals)


def _stuck_of(
    pos: np.ndarray,
    target: np.ndarray,
    moving: np.ndarray,
    present: np.ndarray,
    anchor: np.ndarray,
    anchor_time: np.ndarray,
    now: float,
    patience_s: float,
    out: np.ndarray,
) -> int:
    """Robots making no progress: write into `out` every active robot, away from its target, that
    has stayed within `STUCK_RADIUS_M` of its anchor for `patience_s`; return how many. Anchors
    (position and time) follow each robot whenever it moves further than that, or is inactive or
    at its target."""
    k = 0
    for i in range(pos.shape[0]):
        dx = pos[i, 0] - anchor[i, 0]
        dy = pos[i, 1] - anchor[i, 1]
        tx = target[i, 0] - pos[i, 0]
        ty = target[i, 1] - pos[i, 1]
        waiting = (
            not (moving[i] and present[i])
        ) or tx * tx + ty * ty <= STUCK_RADIUS_M * STUCK_RADIUS_M
        if waiting or dx * dx + dy * dy > STUCK_RADIUS_M * STUCK_RADIUS_M:
            anchor[i, 0] = pos[i, 0]
            anchor[i, 1] = pos[i, 1]
            anchor_time[i] = now
        elif now - anchor_time[i] >= patience_s:
            out[k] = i
            k += 1
    return k


_stuck_of_c = compiled(_stuck_of)
stuck_of = _stuck_of_c


# -- the task rules, compiled --------------------------------------------------------------------
# The rules of `tavc_env.engine.tasks` (see its docstring) on the task cycle's arrays, so that the
# compiled tick runs them itself and returns to Python only at a decision epoch or a random draw.
# They live in this file because the compiled tick calls them (see the note above `_VOID_P`).
# Phase and mode codes (`tavc_env.engine.tasks.Phase`, `Mode` name them)
DECIDING, TO_SOURCE, TO_SINK, BROKEN = 0, 1, 2, 3
IDLE, TRAVEL, QUEUED, DOCKING, SERVICE = 0, 1, 2, 3, 4
NEVER = -1.0  # a trigger that never fires


class TaskArrays(NamedTuple):
    """The task cycle's state as the compiled rules take it: per robot, then per station (source
    of circuit c: 2c, its sink 2c + 1), padded to the largest station, counts saying how much of
    each row is used."""

    phase: np.ndarray
    mode: np.ndarray
    circuit: np.ndarray
    station: np.ndarray  # the station a robot heads for or stands at, -1: none
    bay: np.ndarray  # the bay a docking or served robot holds, -1: none
    decision_time: np.ndarray
    service_until: np.ndarray
    trigger: np.ndarray  # distance to target that fires an event; NEVER: none
    target: np.ndarray  # (n, 2)
    completed: np.ndarray
    moving: np.ndarray  # robots driving toward a target (kept in sync with `mode`)
    service_scale: np.ndarray
    docks: np.ndarray  # (stations, bays, 2) bay positions, the dock first
    n_bays: np.ndarray
    slots: np.ndarray  # (stations, k, 2) waiting positions, in the order the line fills them
    n_slots: np.ndarray
    first_row: np.ndarray  # how many slots stand in the first row, along the wall from the dock
    service_s: np.ndarray
    occupants: np.ndarray  # (stations, bays) the robot in each bay, -1: free
    line: np.ndarray  # (stations, n) the waiting robots, head first
    line_len: np.ndarray
    join_radius_m: float
    dock_tolerance_m: float


def _set_mode(t: TaskArrays, i: int, mode: int) -> None:
    t.mode[i] = mode
    t.moving[i] = TRAVEL <= mode <= DOCKING


set_mode = compiled(_set_mode)


def _aim(t: TaskArrays, i: int, s: int) -> None:
    """Robot i, travelling to station s, drives at its dock, or at the end of a line that has
    spilled beyond its first row."""
    tail = t.line_len[s]
    if t.first_row[s] <= tail < t.n_slots[s]:
        t.target[i, 0] = t.slots[s, tail, 0]
        t.target[i, 1] = t.slots[s, tail, 1]
    else:
        t.target[i, 0] = t.docks[s, 0, 0]
        t.target[i, 1] = t.docks[s, 0, 1]
    t.trigger[i] = t.join_radius_m


_aim_c = compiled(_aim)


def _travel_to(t: TaskArrays, i: int, s: int) -> None:
    t.station[i] = s
    set_mode(t, i, TRAVEL)
    _aim_c(t, i, s)


_travel_to_c = compiled(_travel_to)


def _line_changed(t: TaskArrays, s: int) -> None:
    """Re-aim the robots travelling to station s and move its waiting robots up."""
    for k in range(t.line_len[s]):
        j = t.line[s, k]
        t.target[j, 0] = t.slots[s, k, 0]
        t.target[j, 1] = t.slots[s, k, 1]
    for j in range(t.mode.shape[0]):
        if t.mode[j] == TRAVEL and t.station[j] == s:
            _aim_c(t, j, s)


_line_changed_c = compiled(_line_changed)


def _dock(t: TaskArrays, i: int, s: int, bay: int) -> None:
    t.occupants[s, bay] = i
    t.bay[i] = bay
    set_mode(t, i, DOCKING)
    t.target[i, 0] = t.docks[s, bay, 0]
    t.target[i, 1] = t.docks[s, bay, 1]
    t.trigger[i] = t.dock_tolerance_m


_dock_c = compiled(_dock)


def _free_bay(t: TaskArrays, s: int) -> int:
    """Station s's free bay nearest the dock, or -1."""
    for b in range(t.n_bays[s]):
        if t.occupants[s, b] < 0:
            return b
    return -1


free_bay = compiled(_free_bay)


def _choose(t: TaskArrays, i: int, circuit: int, now: float) -> None:
    """Robot i (deciding) starts a task on `circuit`: off to its source."""
    t.phase[i] = TO_SOURCE
    t.circuit[i] = circuit
    t.decision_time[i] = now
    _travel_to_c(t, i, 2 * circuit)


choose = compiled(_choose)


def _choose_fields(i: int, circuit: int, now: float, *task_fields: Any) -> None:
    """`choose` on the task arrays given field by field, as `TaskCycle.choose` calls it (from
    Python numba takes a named tuple of arrays at several microseconds per call, its fields at
    a fraction of that)."""
    choose(TaskArrays(*task_fields), i, circuit, now)


choose_fields = compiled(_choose_fields)


def _arrive(t: TaskArrays, i: int, now: float) -> None:
    """Robot i reached the distance that fires its current trigger: travelling, it joins the
    station's line (or docks in a free bay); docking, its service starts."""
    if t.mode[i] == TRAVEL:
        s = t.station[i]
        bay = free_bay(t, s)
        if bay >= 0 and t.line_len[s] == 0:
            _dock_c(t, i, s, bay)
        else:
            t.line[s, t.line_len[s]] = i
            t.line_len[s] += 1
            set_mode(t, i, QUEUED)
            t.trigger[i] = NEVER
            _line_changed_c(t, s)
    elif t.mode[i] == DOCKING:
        set_mode(t, i, SERVICE)
        t.trigger[i] = NEVER
        t.service_until[i] = now + t.service_s[t.station[i]] * t.service_scale[i]


arrive = compiled(_arrive)


def _leave_line(t: TaskArrays, s: int, k: int) -> None:
    """The robot at place k of station s's line leaves it; those behind move up one place."""
    for a in range(k, t.line_len[s] - 1):
        t.line[s, a] = t.line[s, a + 1]
    t.line_len[s] -= 1
    t.line[s, t.line_len[s]] = -1


_leave_line_c = compiled(_leave_line)


def _release(t: TaskArrays, i: int) -> None:
    """Robot i leaves its bay; the head of the line, if any, takes it."""
    s = t.station[i]
    bay = t.bay[i]
    t.occupants[s, bay] = -1
    t.bay[i] = -1
    if t.line_len[s] > 0:
        head = t.line[s, 0]
        _leave_line_c(t, s, 0)
        _dock_c(t, head, s, bay)
        _line_changed_c(t, s)


_release_c = compiled(_release)


def _finish_service(t: TaskArrays, i: int) -> bool:
    """Robot i's loading or unloading ended: loaded, it is off to the sink (False); unloaded, its
    task is complete and it must decide (True)."""
    t.service_until[i] = math.inf
    _release_c(t, i)
    if t.phase[i] == TO_SOURCE:
        t.phase[i] = TO_SINK
        _travel_to_c(t, i, 2 * t.circuit[i] + 1)
        return False
    t.phase[i] = DECIDING
    set_mode(t, i, IDLE)
    t.station[i] = -1
    t.trigger[i] = NEVER
    t.completed[i] += 1
    return True


finish_service = compiled(_finish_service)


def _break_down(t: TaskArrays, i: int) -> None:
    """Robot i stops serving: it leaves any line or bay; its task is abandoned."""
    s = t.station[i]
    if s >= 0:
        if t.bay[i] >= 0:
            _release_c(t, i)
        else:
            for k in range(t.line_len[s]):
                if t.line[s, k] == i:
                    _leave_line_c(t, s, k)
                    _line_changed_c(t, s)
                    break
    t.phase[i] = BROKEN
    set_mode(t, i, IDLE)
    t.station[i] = -1
    t.trigger[i] = NEVER
    t.service_until[i] = math.inf


break_down = compiled(_break_down)


def _new_leg_speed(
    i: int,
    speed_noise: float,
    speeds: np.ndarray,
    speed_factor: np.ndarray,
    top_speed: np.ndarray,
    bitgen: np.ndarray,
) -> None:
    """Robot i starts a leg: with speed noise, its speed for the leg is its own times a factor
    1 + `speed_noise` * N(0, 1) clipped to [0.5, 1.5], drawn from the generator `bitgen`
    addresses (`bit_generator_calls`). The one rule for every leg: the compiled tick's (legs to
    the sink) and `Simulation.choose`'s (legs to the source)."""
    if speed_noise > 0.0:
        # np.clip's value, without its cost on a scalar (the draw is never NaN)
        factor = min(max(1.0 + speed_noise * _standard_normal_c(bitgen), 0.5), 1.5)
        speed_factor[i] = factor
        top_speed[i] = speeds[i] * factor


_new_leg_speed_c = compiled(_new_leg_speed, inline=True)


def _choose_leg(
    i: int,
    circuit: int,
    now: float,
    speed_noise: float,
    speeds: np.ndarray,
    speed_factor: np.ndarray,
    top_speed: np.ndarray,
    bitgen: np.ndarray,
    *task_fields: Any,
) -> None:
    """`Simulation.choose` in one call: `choose` on the task arrays given field by field, then
    the leg to the source gets its speed (`_new_leg_speed`)."""
    choose(TaskArrays(*task_fields), i, circuit, now)
    _new_leg_speed_c(i, speed_noise, speeds, speed_factor, top_speed, bitgen)


choose_leg = compiled(_choose_leg)
_CHOICE_SCALARS = (types.int64, types.int64, types.float64)
"""`choose_leg`'s leading argument types: robot, circuit, time"""


def choice_entry(
    task_fields: tuple[object, ...],
    speed_noise: float,
    speeds: np.ndarray,
    speed_factor: np.ndarray,
    top_speed: np.ndarray,
    bitgen: np.ndarray,
) -> Callable[[int, int, float], None]:
    """`choose_leg` bound to an arena's arrays (`bound_entry`): `(robot, circuit, now)`."""
    head = (float(speed_noise), speeds, speed_factor, top_speed, bitgen)
    return bound_entry(choose_leg, _CHOICE_SCALARS, head, tuple(task_fields))


def _end_services(
    t: TaskArrays,
    now: float,
    done: np.ndarray,
    speed_noise: float,
    speeds: np.ndarray,
    speed_factor: np.ndarray,
    top_speed: np.ndarray,
    bitgen: np.ndarray,
) -> int:
    """The services due at `now` end, robot by robot. Writes the robots that completed a task
    into `done` and returns how many; a robot that starts its leg to the sink gets its speed
    for the leg (`_new_leg_speed`, in robot order)."""
    n_done = 0
    for i in range(t.service_until.shape[0]):
        if t.service_until[i] <= now + 1e-9:
            if finish_service(t, i):
                done[n_done] = i
                n_done += 1
            else:
                _new_leg_speed_c(i, speed_noise, speeds, speed_factor, top_speed, bitgen)
    return n_done


end_services = compiled(_end_services)


class Navigator:
    """The controller's constants for one arena (the compiled functions above take them)."""

    def __init__(self, config: ArenaConfig) -> None:
        self.radius = config.robot_radius
        self.sensing = config.sensing_range_m
        self.governor = config.clearance_governor_m
        self.overtaking = config.overtaking
        self.turn_step = config.max_turn_rate * config.dt
        self.width = config.width
        self.height = config.height


# -- the compiled tick ---------------------------------------------------------------------------
# Steer, push velocities, step Chipmunk, read positions, run the task rules (services ending,
# arrivals) and check stuck robots, tick after tick, without returning to Python while nothing
# needs it. Each tick makes the calls a tick driven from Python made, in the same order and on the
# same arrays (the controller above, pymunk's batch iterators and `cpSpaceStep` through the
# addresses in `World.c_calls`, the task rules above), so trajectories are bit for bit the same.
# The loop hands back to `Simulation` the first tick whose end needs Python (a completion, a new
# leg's speed draw, a schedule entry due, a stuck robot, a jam check); Python finishes that tick
# (`Simulation._end_tick`). It lives in this file with every compiled function it calls:
# numba's on-disk cache of a function is renewed when its own file changes, not when a function
# it calls in another file does.
# Addresses travel as int64 (numba's type of a Python int) and become pointers only in the call.
_VOID_P = ir.IntType(8).as_pointer()


def _space_step(typingctx: object, fn: types.Type, space: types.Type, dt: types.Type) -> object:
    """`cpSpaceStep(space, dt)` through its address `fn`."""

    def codegen(
        context: object, builder: ir.IRBuilder, sig: object, args: list[ir.Value]
    ) -> object:
        kind = ir.FunctionType(ir.VoidType(), [_VOID_P, ir.DoubleType()])
        call = builder.inttoptr(args[0], kind.as_pointer())
        builder.call(call, [builder.inttoptr(args[1], _VOID_P), args[2]])
        return context.get_dummy_value()  # type: ignore[attr-defined]

    return types.void(types.int64, types.int64, types.float64), codegen


def _each_body(
    typingctx: object, fn: types.Type, space: types.Type, visit: types.Type, data: types.Type
) -> object:
    """`cpSpaceEachBody(space, visit, data)` through its address `fn`."""

    def codegen(
        context: object, builder: ir.IRBuilder, sig: object, args: list[ir.Value]
    ) -> object:
        kind = ir.FunctionType(ir.VoidType(), [_VOID_P, _VOID_P, _VOID_P])
        call = builder.inttoptr(args[0], kind.as_pointer())
        builder.call(call, [builder.inttoptr(a, _VOID_P) for a in args[1:]])
        return context.get_dummy_value()  # type: ignore[attr-defined]

    return types.void(types.int64, types.int64, types.int64, types.int64), codegen


def _set_count(typingctx: object, array: types.Type, count: types.Type) -> object:
    """Set the `num` (an int, first field) of the pymunk float array at address `array`; return
    the old one. pymunk's batch iterators read and write from index `num` on, advancing it."""

    def codegen(
        context: object, builder: ir.IRBuilder, sig: object, args: list[ir.Value]
    ) -> object:
        at = builder.inttoptr(args[0], ir.IntType(32).as_pointer())
        old = builder.load(at)
        builder.store(builder.trunc(args[1], ir.IntType(32)), at)
        return builder.sext(old, ir.IntType(64))

    return types.int64(types.int64, types.int64), codegen


def _call_uint64(typingctx: object, fn: types.Type, state: types.Type) -> object:
    """`fn(state)` for a C function `uint64_t fn(void *)` at address `fn` (a numpy bit
    generator's `next_uint64`)."""

    def codegen(
        context: object, builder: ir.IRBuilder, sig: object, args: list[ir.Value]
    ) -> object:
        kind = ir.FunctionType(ir.IntType(64), [_VOID_P])
        call = builder.inttoptr(args[0], kind.as_pointer())
        return builder.call(call, [builder.inttoptr(args[1], _VOID_P)])

    return types.uint64(types.int64, types.int64), codegen


def _call_double(typingctx: object, fn: types.Type, state: types.Type) -> object:
    """`fn(state)` for a C function `double fn(void *)` at address `fn` (`next_double`)."""

    def codegen(
        context: object, builder: ir.IRBuilder, sig: object, args: list[ir.Value]
    ) -> object:
        kind = ir.FunctionType(ir.DoubleType(), [_VOID_P])
        call = builder.inttoptr(args[0], kind.as_pointer())
        return builder.call(call, [builder.inttoptr(args[1], _VOID_P)])

    return types.float64(types.int64, types.int64), codegen


# numba's intrinsic wrappers (callable from compiled code only)
space_step: Any = intrinsic(_space_step)
each_body: Any = intrinsic(_each_body)
set_count: Any = intrinsic(_set_count)
call_uint64: Any = intrinsic(_call_uint64)
call_double: Any = intrinsic(_call_double)

# indices into a bit generator's addresses (`bit_generator_calls`)
B_STATE, B_NEXT_UINT64, B_NEXT_DOUBLE = 0, 1, 2


def bit_generator_calls(rng: np.random.Generator) -> np.ndarray:
    """The addresses through which compiled code draws from `rng` itself, in its stream: its
    bit generator's state, `next_uint64` and `next_double` (numpy's C interface; valid while
    `rng` lives)."""
    c = rng.bit_generator.ctypes
    fns = (c.next_uint64, c.next_double)
    return np.array(
        [c.state_address, *(ctypes.cast(f, ctypes.c_void_p).value for f in fns)], dtype=np.int64
    )


def _standard_normal(bitgen: np.ndarray) -> float:
    """`rng.standard_normal()` of the generator `bitgen` addresses (`bit_generator_calls`):
    numpy's ziggurat (`random_standard_normal` in numpy's distributions.c, as numba's own
    Generator support translates it, with its tables), the same draws in the same order, bit
    for bit (tests/tavc_env/engine/test_engine_batch.py checks it against numpy)."""
    state = bitgen[B_STATE]
    while True:
        r = call_uint64(bitgen[B_NEXT_UINT64], state)
        idx = r & 0xFF
        r >>= 8
        sign = r & 0x1
        rabs = (r >> 1) & 0x000FFFFFFFFFFFFF
        x = rabs * _ZIG_W[idx]
        if sign & 0x1:
            x = -x
        if rabs < _ZIG_K[idx]:
            return x
        if idx == 0:
            while True:
                xx = -_ZIG_INV_R * np.log1p(-call_double(bitgen[B_NEXT_DOUBLE], state))
                yy = -np.log1p(-call_double(bitgen[B_NEXT_DOUBLE], state))
                if yy + yy > xx * xx:
                    if (rabs >> 8) & 0x1:
                        return -(_ZIG_R + xx)
                    return _ZIG_R + xx
        else:
            u = call_double(bitgen[B_NEXT_DOUBLE], state)
            if (_ZIG_F[idx - 1] - _ZIG_F[idx]) * u + _ZIG_F[idx] < np.exp(-0.5 * x * x):
                return x


_standard_normal_c = compiled(_standard_normal, inline=True)

# indices into `World.c_calls` (tavc_env.engine.world fills it)
C_STEP, C_EACH_BODY, C_SPACE, C_SET_VISIT, C_SET_DATA, C_SET_FLOATS = 0, 1, 2, 3, 4, 5
C_GET_VISIT, C_GET_DATA, C_GET_FLOATS = 6, 7, 8


QUIET = 0  # every tick ran to its end with no event for Python
SCHEDULE = 1  # the last tick's task events ran; a schedule entry is due: Python runs it, then the
# stuck check, and finishes the tick
HANDBACK = 2  # the last tick's task events and stuck check ran; Python finishes the tick
# (completions, escapes, the jam watch)


class TickArgs(NamedTuple):
    """The loop's arrays and constants, bound once (rebuilt when the world's slots change, the
    task cycle is replaced, or robots' headings or speeds arrays are)."""

    c_calls: np.ndarray  # World.c_calls
    pos: np.ndarray  # (n, 2) World.pos, written after each step
    heading: np.ndarray
    target: np.ndarray
    moving: np.ndarray
    top_speed: np.ndarray
    present: np.ndarray
    radius: float
    sensing: float
    governor: float
    overtaking: bool
    turn_step: float
    width: float
    height: float
    velocity: np.ndarray  # (n, 2) World.velocity_out, the commands
    cell: float  # the neighbour grid's cell; 0: all pairs
    # the world's scatter, when its batch order is not the robots' (after a breakdown)
    in_order: bool
    robots_in: np.ndarray
    slots: np.ndarray
    positions_in: np.ndarray
    velocities_in: np.ndarray
    # escapes, the after-step checks
    escape_until: np.ndarray
    escape_target: np.ndarray
    aim: np.ndarray  # (n, 2) scratch: the targets steered at while someone escapes
    trigger: np.ndarray
    anchor: np.ndarray
    anchor_time: np.ndarray
    patience_s: float
    arrived: np.ndarray
    stalled: np.ndarray
    # the task rules' outputs (robots that completed a task), the legs' speed draws (the
    # config's speed noise, base speeds, each robot's factor for its leg, the generator's
    # `bit_generator_calls`), the jam watch's positions at the last task event (the rules'
    # state, a `TaskArrays`, follows these arguments field by field: numba takes a named tuple
    # argument at several microseconds per call, its fields at a tenth of that)
    done: np.ndarray
    speed_noise: float
    speeds: np.ndarray
    speed_factor: np.ndarray
    bitgen: np.ndarray
    progress_pos: np.ndarray
    # scratch kept from call to call: arange(n) for all pairs, the neighbour grid's arrays and
    # its neighbour lists (`grid_scratch`)
    everyone: np.ndarray
    grid_cx: np.ndarray
    grid_cy: np.ndarray
    grid_key: np.ndarray
    grid_order: np.ndarray
    grid_keys: np.ndarray
    grid_others: np.ndarray
    grid_held: np.ndarray
    near: np.ndarray
    near_start: np.ndarray
    near_anchor: np.ndarray
    near_present: np.ndarray
    near_held: np.ndarray


def _run_ticks(
    max_ticks: int,
    ticks: int,
    dt: float,
    escapes_end: float,
    next_service: float,
    next_schedule: float,
    progress_s: float,
    jam_window_s: float,
    jammed: bool,
    c_calls: np.ndarray,
    pos: np.ndarray,
    heading: np.ndarray,
    target: np.ndarray,
    moving: np.ndarray,
    top_speed: np.ndarray,
    present: np.ndarray,
    radius: float,
    sensing: float,
    governor: float,
    overtaking: bool,
    turn_step: float,
    width: float,
    height: float,
    velocity: np.ndarray,
    cell: float,
    in_order: bool,
    robots_in: np.ndarray,
    slots: np.ndarray,
    positions_in: np.ndarray,
    velocities_in: np.ndarray,
    escape_until: np.ndarray,
    escape_target: np.ndarray,
    aim: np.ndarray,
    trigger: np.ndarray,
    anchor: np.ndarray,
    anchor_time: np.ndarray,
    patience_s: float,
    arrived: np.ndarray,
    stalled: np.ndarray,
    done: np.ndarray,
    speed_noise: float,
    speeds: np.ndarray,
    speed_factor: np.ndarray,
    bitgen: np.ndarray,
    progress_pos: np.ndarray,
    everyone: np.ndarray,
    grid_cx: np.ndarray,
    grid_cy: np.ndarray,
    grid_key: np.ndarray,
    grid_order: np.ndarray,
    grid_keys: np.ndarray,
    grid_others: np.ndarray,
    grid_held: np.ndarray,
    near: np.ndarray,
    near_start: np.ndarray,
    near_anchor: np.ndarray,
    near_present: np.ndarray,
    near_held: np.ndarray,
    *task_fields: Any,
) -> tuple[int, int, int, int, bool, bool, float, float]:
    """Up to `max_ticks` ticks from tick number `ticks`, each with its task events (and the
    speed draws of legs that start), stopping after the first tick that needs Python: a
    completion (a decision epoch), a schedule entry due, a stuck robot, a jam check. Returns
    (ticks run, QUIET / SCHEDULE / HANDBACK, completed, stalled (-1: not checked yet), whether
    the last tick had a task event, whether its progress was recorded here, the next service
    end, the progress time)."""
    tasks = TaskArrays(*task_fields)
    space = c_calls[C_SPACE]
    each = c_calls[C_EACH_BODY]
    for k in range(max_ticks):
        steer_at = target
        if escapes_end > ticks * dt:  # Simulation.time_s before this tick
            now_before = ticks * dt
            for i in range(target.shape[0]):
                src = escape_target if escape_until[i] > now_before else target
                aim[i, 0] = src[i, 0]
                aim[i, 1] = src[i, 1]
            steer_at = aim
        if cell > 0.0:
            steer_near_into(
                pos, heading, steer_at, moving, top_speed, present, radius, sensing, governor,
                overtaking, turn_step, width, height, velocity, heading, cell, grid_cx, grid_cy,
                grid_key, grid_order, grid_keys, grid_others, grid_held, near, near_start,
                near_anchor, near_present, near_held,
            )  # fmt: skip
        else:
            _steer_pairs_c(
                pos, heading, steer_at, moving, top_speed, present, radius, sensing, governor,
                overtaking, turn_step, width, height, velocity, heading, everyone,
            )  # fmt: skip
        # World.push_velocities, World.step, World.sync_positions
        if not in_order:
            for j in range(robots_in.shape[0]):
                velocities_in[slots[j], 0] = velocity[robots_in[j], 0]
                velocities_in[slots[j], 1] = velocity[robots_in[j], 1]
        count = set_count(c_calls[C_SET_FLOATS], 0)
        each_body(each, space, c_calls[C_SET_VISIT], c_calls[C_SET_DATA])
        set_count(c_calls[C_SET_FLOATS], count)
        space_step(c_calls[C_STEP], space, dt)
        set_count(c_calls[C_GET_FLOATS], 0)
        each_body(each, space, c_calls[C_GET_VISIT], c_calls[C_GET_DATA])
        if not in_order:
            for j in range(robots_in.shape[0]):
                pos[robots_in[j], 0] = positions_in[slots[j], 0]
                pos[robots_in[j], 1] = positions_in[slots[j], 1]
        ticks += 1
        now = ticks * dt
        # the task rules at the end of the tick: services ending, then arrivals (the order of
        # the rules; Simulation._end_tick does what is left to Python after them)
        services_due = next_service <= now + 1e-9
        schedule_due = next_schedule <= now + 1e-9
        n_done = 0
        if services_due:
            n_done = end_services(
                tasks, now, done, speed_noise, speeds, speed_factor, top_speed, bitgen
            )
        # then the arrivals: all found first, then handled robot by robot
        n_arrived = _arrivals_c(pos, target, trigger, arrived)
        for a in range(n_arrived):
            arrive(tasks, arrived[a], now)
        event = services_due or n_arrived > 0 or schedule_due
        if event:
            next_service = math.inf
            for i in range(tasks.service_until.shape[0]):
                next_service = min(next_service, tasks.service_until[i])
        if schedule_due:
            return k + 1, SCHEDULE, n_done, -1, event, False, next_service, progress_s
        n_stalled = _stuck_of_c(
            pos, target, moving, present, anchor, anchor_time, now, patience_s, stalled
        )
        progressed = False
        if event and not jammed and n_stalled == 0:
            # Simulation.progress (a jam's end is Python's to record)
            progress_s = now
            for i in range(pos.shape[0]):
                progress_pos[i, 0] = pos[i, 0]
                progress_pos[i, 1] = pos[i, 1]
            progressed = True
        if (
            n_done != 0
            or n_stalled != 0
            or (event and not progressed)
            or (not event and now - progress_s >= jam_window_s)
        ):
            return (
                k + 1,
                HANDBACK,
                n_done,
                n_stalled,
                event,
                progressed,
                next_service,
                progress_s,
            )
    return max_ticks, QUIET, 0, 0, False, False, next_service, progress_s


run_ticks = compiled(_run_ticks)

_TICK_SCALARS = (types.int64, types.int64, *([types.float64] * 6), types.boolean)
"""the types of `run_ticks`' leading arguments, max_ticks to jammed (fixed, so that a value that
happens to be an int where a time is expected cannot select an integer signature)"""


def bound_entry(
    fn: Callable[..., Any],
    scalars: tuple[Any, ...],
    head: tuple[object, ...],
    fields: tuple[object, ...],
) -> Callable[..., Any]:
    """Compiled `fn` as called with leading arguments of numba types `scalars`, then `head`, then
    star arguments `fields`: a function of those scalars alone, calling the compiled entry of
    these arguments' types directly (compiled, or loaded from the disk cache, here if need be),
    without numba's type dispatch over every argument at every call. Bind again when `head` or
    `fields` change."""
    dispatcher: Any = fn  # (numba's Dispatcher: `compiled` returns it as a callable)
    typeof = dispatcher.typeof_pyval
    # (numba passes star arguments to the compiled code as one tuple, and types them so)
    entry = dispatcher.compile((*scalars, *(typeof(a) for a in head), typeof(fields)))
    return lambda *leading: entry(*leading, *head, fields)


def tick_loop(bound: tuple[object, ...]) -> Callable[..., Any]:
    """`run_ticks` as called with `bound` (`TickArgs`, then the task rules' arrays) after its
    leading scalars (`bound_entry`: numba's type dispatch over 81 arguments cost 1.5 us of the
    2.5 a call took). Bind again when `bound` changes."""
    head, fields = bound[: len(TickArgs._fields)], bound[len(TickArgs._fields) :]
    return bound_entry(run_ticks, _TICK_SCALARS, head, fields)


def _replay_commands(
    c_calls: np.ndarray, commands: np.ndarray, velocities_in: np.ndarray, dt: float
) -> None:
    """The compiled physics floor (`tavc_env.measurement.compiled_floor`): every tick, the
    recorded commands `commands[t]` (n, 2) written into the batch buffer `velocities_in`, then
    the compiled tick's own Chipmunk calls (batch velocity write, `cpSpaceStep`, batch position
    read), and nothing else. Every robot must be on the floor in index order (`World`'s
    `in_order`)."""
    space = c_calls[C_SPACE]
    each = c_calls[C_EACH_BODY]
    n = commands.shape[1]
    for t in range(commands.shape[0]):
        for i in range(n):
            velocities_in[i, 0] = commands[t, i, 0]
            velocities_in[i, 1] = commands[t, i, 1]
        count = set_count(c_calls[C_SET_FLOATS], 0)
        each_body(each, space, c_calls[C_SET_VISIT], c_calls[C_SET_DATA])
        set_count(c_calls[C_SET_FLOATS], count)
        space_step(c_calls[C_STEP], space, dt)
        set_count(c_calls[C_GET_FLOATS], 0)
        each_body(each, space, c_calls[C_GET_VISIT], c_calls[C_GET_DATA])


replay_commands = compiled(_replay_commands)


def compiled_cache_ready() -> bool | None:
    """Whether numba's disk cache holds the compiled tick (`run_ticks`) for this source, so that
    a trial starts at once; False if the first call will compile it (a fresh install or
    NUMBA_CACHE_DIR, an edited source, a cache that cannot be written: about 7 CPU s, a minute
    or more of wall time on a loaded machine); None if numba's cache cannot be looked at."""
    try:
        if getattr(run_ticks, "signatures", None):  # compiled (or loaded) in this process already
            return True
        cache = getattr(run_ticks, "_cache", None)
        cache_file = getattr(cache, "_cache_file", None)
        if cache_file is None:  # compiled without a cache (no folder numba may write)
            return False
        return bool(cache_file._load_index())  # empty: no index, or one of another source
    except Exception:  # numba's private cache API changed: say nothing rather than guess
        return None
