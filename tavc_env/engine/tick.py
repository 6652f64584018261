"""The physics tick in compiled code: steer, push velocities, step Chipmunk, read positions, and
check arrivals and stuck robots, tick after tick, without returning to Python while nothing
happens.

Each tick makes the calls the Python tick made, in the same order and on the same arrays
(the controller of `navigation`, pymunk's batch iterators and `cpSpaceStep` through the addresses
in `World.c_calls`), so trajectories are bit for bit those of a tick driven from Python. The loop
hands back to `Simulation` the first tick whose end needs the task rules: a service or schedule
entry due, an arrival, a stuck robot or a jam check; Python finishes that tick.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tavc_env.engine import world as w
from tavc_env.engine.navigation import after_step, compiled, steer_all, steer_all_grid

QUIET = 0  # every tick ran to its end: nothing for the task rules
DUE = 1  # the last tick's physics ran; a service or schedule entry is due: Python checks it all
CHECKED = 2  # the last tick's physics and after-step check ran; its results need the task rules


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


def _run_ticks(
    max_ticks: int,
    ticks: int,
    dt: float,
    escapes_end: float,
    next_service: float,
    next_schedule: float,
    progress_s: float,
    jam_window_s: float,
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
) -> tuple[int, int, int, int]:
    """Up to `max_ticks` ticks from tick number `ticks`. Returns (ticks run, QUIET / DUE /
    CHECKED, arrived count, stalled count) with the counts of `after_step` if CHECKED."""
    space = c_calls[w.C_SPACE]
    each = c_calls[w.C_EACH_BODY]
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
            steer_all_grid(
                pos, heading, steer_at, moving, top_speed, present, radius, sensing, governor,
                turn_step, width, height, velocity, heading, cell,
            )  # fmt: skip
        else:
            steer_all(
                pos, heading, steer_at, moving, top_speed, present, radius, sensing, governor,
                turn_step, width, height, velocity, heading,
            )  # fmt: skip
        # World.push_velocities, World.step, World.sync_positions
        if not in_order:
            for j in range(robots_in.shape[0]):
                velocities_in[slots[j], 0] = velocity[robots_in[j], 0]
                velocities_in[slots[j], 1] = velocity[robots_in[j], 1]
        count = w.set_count(c_calls[w.C_SET_FLOATS], 0)
        w.each_body(each, space, c_calls[w.C_SET_VISIT], c_calls[w.C_SET_DATA])
        w.set_count(c_calls[w.C_SET_FLOATS], count)
        w.space_step(c_calls[w.C_STEP], space, dt)
        w.set_count(c_calls[w.C_GET_FLOATS], 0)
        w.each_body(each, space, c_calls[w.C_GET_VISIT], c_calls[w.C_GET_DATA])
        if not in_order:
            for j in range(robots_in.shape[0]):
                pos[robots_in[j], 0] = positions_in[slots[j], 0]
                pos[robots_in[j], 1] = positions_in[slots[j], 1]
        ticks += 1
        now = ticks * dt
        # the first checks of Simulation._post_step, in its order
        if next_service <= now + 1e-9 or next_schedule <= now + 1e-9:
            return k + 1, DUE, 0, 0
        n_arrived, n_stalled = after_step(
            pos, target, trigger, moving, present, anchor, anchor_time, now, patience_s, True,
            arrived, stalled,
        )  # fmt: skip
        if n_arrived != 0 or n_stalled != 0 or now - progress_s >= jam_window_s:
            return k + 1, CHECKED, n_arrived, n_stalled
    return max_ticks, QUIET, 0, 0


run_ticks = compiled(_run_ticks)
