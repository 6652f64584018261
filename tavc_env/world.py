"""The pymunk world: walls and disc robots with real collisions. Knows nothing of tasks or learning.

Robots are dynamic discs with infinite moment (they do not spin on contact; their heading is the
controller's state). The controller sets each robot's velocity every tick and pymunk resolves the
contacts, so robots that drive into each other are stopped and pushed apart physically.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from tavc_env.config import ArenaConfig

ROBOT_MASS_KG = 9.0  # a Pioneer 2DX weighs about 9 kg
WALL_THICKNESS_M = 0.05
ROBOT_CATEGORY = 0b01
WALL_CATEGORY = 0b10


class World:
    """Walls and robot bodies for one arena; positions and velocities as numpy arrays."""

    def __init__(self, config: ArenaConfig) -> None:
        self.config = config
        self.space = pymunk.Space()
        self.space.iterations = 10
        # pymunk's default slop (0.1 units = 10 cm here) would let discs sink visibly into each other.
        self.space.collision_slop = 0.002
        self.space.collision_bias = pow(1.0 - 0.3, 60.0)
        w, h = config.width, config.height
        corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
        self.walls = []
        for a, b in zip(corners, corners[1:] + corners[:1]):
            seg = pymunk.Segment(self.space.static_body, a, b, WALL_THICKNESS_M)
            seg.friction = 0.0
            seg.elasticity = 0.0
            seg.filter = pymunk.ShapeFilter(categories=WALL_CATEGORY)
            self.walls.append(seg)
        self.space.add(*self.walls)
        self.bodies: list[pymunk.Body] = []
        self.shapes: list[pymunk.Circle] = []
        for _ in config.robots:
            body = pymunk.Body(ROBOT_MASS_KG, math.inf)
            shape = pymunk.Circle(body, config.robot_radius)
            shape.friction = 0.0
            shape.elasticity = 0.0
            shape.filter = pymunk.ShapeFilter(categories=ROBOT_CATEGORY)
            self.bodies.append(body)
            self.shapes.append(shape)
            self.space.add(body, shape)
        self.in_space = np.ones(len(self.bodies), dtype=bool)

    @property
    def n(self) -> int:
        return len(self.bodies)

    def place(self, positions: np.ndarray) -> None:
        """Teleport every robot (used at reset) and stop it."""
        for body, (x, y) in zip(self.bodies, positions):
            body.position = (float(x), float(y))
            body.velocity = (0.0, 0.0)
        for body in self.bodies:
            self.space.reindex_shapes_for_body(body)

    def positions(self) -> np.ndarray:
        """Robot centres, shape (n, 2)."""
        return np.array([tuple(b.position) for b in self.bodies], dtype=np.float64)

    def velocities(self) -> np.ndarray:
        """Robot velocities, shape (n, 2)."""
        return np.array([tuple(b.velocity) for b in self.bodies], dtype=np.float64)

    def set_velocities(self, velocities: np.ndarray) -> None:
        for body, v in zip(self.bodies, velocities.tolist()):
            body.velocity = v

    def step(self, dt: float) -> None:
        self.space.step(dt)

    def remove_robot(self, i: int) -> None:
        """Take robot i off the floor (a broken robot is carried out for repair)."""
        if self.in_space[i]:
            self.bodies[i].velocity = (0.0, 0.0)
            self.space.remove(self.bodies[i], self.shapes[i])
            self.in_space[i] = False

    def restore_robot(self, i: int, rng: np.random.Generator) -> None:
        """Put robot i back where it was, or at the nearest free spot if someone stands there now."""
        if self.in_space[i]:
            return
        body = self.bodies[i]
        home = np.array(body.position, dtype=float)
        spot = self.free_spot_near(home, exclude=i, rng=rng)
        body.position = (float(spot[0]), float(spot[1]))
        body.velocity = (0.0, 0.0)
        self.space.add(body, self.shapes[i])
        self.in_space[i] = True

    def free_spot_near(
        self, point: np.ndarray, exclude: int, rng: np.random.Generator
    ) -> np.ndarray:
        """The nearest point to `point` (on growing rings) where a robot overlaps nobody and no wall."""
        r = self.config.robot_radius
        others = [
            np.array(b.position)
            for j, b in enumerate(self.bodies)
            if j != exclude and self.in_space[j]
        ]
        lo = np.array([r + WALL_THICKNESS_M, r + WALL_THICKNESS_M])
        hi = np.array([self.config.width, self.config.height]) - lo
        phase = rng.uniform(0, 2 * math.pi)
        for ring in range(0, 40):
            radius = ring * r
            count = 1 if ring == 0 else 6 * ring
            for k in range(count):
                a = phase + 2 * math.pi * k / count
                p = point + radius * np.array([math.cos(a), math.sin(a)])
                if np.any(p < lo) or np.any(p > hi):
                    continue
                if all(np.hypot(*(p - q)) >= 2 * r + 0.02 for q in others):
                    return p
        raise RuntimeError("no free spot in the arena to put a repaired robot back")
