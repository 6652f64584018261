"""The robots' low-level controller: drive to a target point, avoid walls and other robots.

Behaviour-based and reactive, like the paper's Pioneers in an open room. Computed for all robots at
once with numpy (no per-robot Python in the physics loop). Each robot is a unicycle: it turns at a
bounded rate and drives forward along its heading. Three behaviours are blended:

* *go to target*: head for the target point, slowing down over the last metre;
* *avoid*: a robot ahead in the way (closer than the target, inside the corridor the robot sweeps)
  deflects the desired heading sideways, away from it, and robots dead ahead are passed on the
  right; so a faster robot overtakes a slower one where there is room, and robots meeting head-on
  pass each other;
* *keep apart*: robots closer than a small margin push away from each other and from walls.

Speed is capped by the free distance along the current heading (a robot brakes behind a robot it
cannot yet pass) and by the heading error (it turns on the spot when the target is behind it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tavc_env.config import ArenaConfig

STEER_GAIN = 1.5  # sideways deflection per unit of obstacle weight
CORRIDOR_MARGIN_M = 0.15  # extra width beyond two radii that counts as "in the way"
KEEP_APART_MARGIN_M = 0.08
BRAKE_DISTANCE_M = 0.3  # free distance below which a robot slows linearly to a stop
BRAKE_GAP_M = 0.03
APPROACH_TIME_S = 1.0  # speed near the target is capped at distance / this time
ARRIVED_M = 0.03  # closer than this to its target a robot holds still
WALL_RANGE_M = 0.25


def _clip(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    # np.clip's Python-level dispatch costs more than the arithmetic on arrays this small.
    return np.minimum(np.maximum(x, lo), hi)


@dataclass(frozen=True)
class Command:
    velocity: np.ndarray  # (n, 2) m/s
    heading: np.ndarray  # (n,) rad


class Navigator:
    """Vectorised controller for all robots of one arena."""

    def __init__(self, config: ArenaConfig) -> None:
        self.radius = config.robot_radius
        self.sensing = config.sensing_range_m
        self.turn_step = config.max_turn_rate * config.dt
        self.width = config.width
        self.height = config.height
        n = config.n_robots
        self._not_self = ~np.eye(n, dtype=bool)

    def command(
        self,
        pos: np.ndarray,
        heading: np.ndarray,
        target: np.ndarray,
        moving: np.ndarray,
        top_speed: np.ndarray,
        present: np.ndarray,
    ) -> Command:
        """Velocities and new headings for one tick.

        `moving`: robots that drive toward their target this tick (others stand still but are still
        obstacles); `present`: robots physically on the floor; `top_speed`: each robot's speed now.
        """
        r = self.radius
        to_goal = target - pos
        gdist = np.hypot(to_goal[:, 0], to_goal[:, 1])
        u = to_goal / np.maximum(gdist, 1e-9)[:, None]

        d = pos[None, :, :] - pos[:, None, :]  # d[i, j] = p_j - p_i
        dx, dy = d[..., 0], d[..., 1]
        dist = np.hypot(dx, dy)
        valid = self._not_self & present[None, :]
        dist = np.where(valid, dist, np.inf)

        # Avoid: obstacles ahead (relative to the goal direction), before the goal, in the corridor.
        ux, uy = u[:, 0:1], u[:, 1:2]
        ahead = dx * ux + dy * uy
        lateral = ux * dy - uy * dx  # > 0: obstacle on the left
        corridor = 2 * r + CORRIDOR_MARGIN_M
        in_way = (ahead > 0) & (np.abs(lateral) < corridor) & (dist < self.sensing)
        in_way &= dist < gdist[:, None]
        weight = _clip((self.sensing - dist) / (self.sensing - 2 * r), 0.0, 1.0)
        weight = weight * (1.0 - np.abs(lateral) / corridor) * in_way
        side = np.where(lateral < 0, -1.0, 1.0)  # +1 = steer right
        steer = _clip((weight * side).sum(axis=1), -2.0, 2.0)
        right = np.stack([u[:, 1], -u[:, 0]], axis=1)
        desired = u + STEER_GAIN * steer[:, None] * right

        # Keep apart from robots that are too close, whatever the direction.
        near = 2 * r + KEEP_APART_MARGIN_M
        overlap = _clip((near - dist) / KEEP_APART_MARGIN_M, 0.0, 2.0)
        inv = overlap / np.maximum(dist, 1e-9)
        desired[:, 0] -= (inv * dx).sum(axis=1)
        desired[:, 1] -= (inv * dy).sum(axis=1)

        # Keep off the walls.
        lo = r + WALL_RANGE_M
        x, y = pos[:, 0], pos[:, 1]
        desired[:, 0] += _clip((lo - x) / WALL_RANGE_M, 0, 1) - _clip(
            (x - (self.width - lo)) / WALL_RANGE_M, 0, 1
        )
        desired[:, 1] += _clip((lo - y) / WALL_RANGE_M, 0, 1) - _clip(
            (y - (self.height - lo)) / WALL_RANGE_M, 0, 1
        )

        active = moving & present & (gdist > ARRIVED_M)
        phi = np.arctan2(desired[:, 1], desired[:, 0])
        err = (phi - heading + math.pi) % (2 * math.pi) - math.pi
        turn = _clip(err, -self.turn_step, self.turn_step)
        new_heading = np.where(active, heading + turn, heading)
        remaining = err - turn

        speed = top_speed * _clip(np.cos(remaining), 0.0, 1.0) ** 2
        speed = np.minimum(speed, gdist / APPROACH_TIME_S)

        # Brake for robots in the swept corridor along the actual heading.
        hx, hy = np.cos(new_heading)[:, None], np.sin(new_heading)[:, None]
        along = dx * hx + dy * hy
        across = np.abs(hx * dy - hy * dx)
        contact = 2 * r
        blocking = (along > 0) & (across < contact)
        gap = along - np.sqrt(np.maximum(contact**2 - across**2, 0.0))
        free = np.where(blocking, gap, np.inf).min(axis=1)
        speed = speed * _clip((free - BRAKE_GAP_M) / BRAKE_DISTANCE_M, 0.0, 1.0)

        speed = np.where(active, speed, 0.0)
        velocity = np.stack([speed * np.cos(new_heading), speed * np.sin(new_heading)], axis=1)
        return Command(velocity=velocity, heading=new_heading)
