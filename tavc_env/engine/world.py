"""The pymunk world: walls and disc robots with real collisions. Knows nothing of tasks or learning.

Robots are dynamic discs with infinite moment (they do not spin on contact; their heading is the
controller's state). The controller sets each robot's velocity every tick and pymunk resolves the
contacts, so robots that drive into each other are stopped and pushed apart physically.

Positions are read and velocities written every tick for all robots at once through pymunk's batch
API (one C call each instead of a Python attribute access per body, which dominated the tick). The
batch visits bodies in the space's own order, so the world keeps the slot of each robot in it.

The engine's compiled tick (`tavc_env.engine.navigation.run_ticks`) makes the same C calls
(Chipmunk's step and pymunk's batch iterators) from compiled code, through the addresses in
`World.c_calls`, without a trip through Python per tick.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pymunk
import pymunk.batch
from pymunk._chipmunk_cffi import ffi as _ffi
from pymunk._chipmunk_cffi import lib as _lib

from tavc_env.config import ArenaConfig
from tavc_env.engine.navigation import (
    C_EACH_BODY,
    C_GET_DATA,
    C_GET_FLOATS,
    C_GET_VISIT,
    C_SET_DATA,
    C_SET_FLOATS,
    C_SET_VISIT,
    C_SPACE,
    C_STEP,
)

# pymunk's own C iterators behind pymunk.batch (pymunk 7; pinned < 8 in pyproject.toml)
_GET_BODIES = _ffi.addressof(_lib, "pmSpaceBodyGetIteratorFuncBatched")
_SET_BODIES = _ffi.addressof(_lib, "pmSpaceBodySetIteratorFuncBatched")
ROBOT_MASS_KG = 9.0  # a Pioneer 2DX weighs about 9 kg
WALL_THICKNESS_M = 0.05
ROBOT_CATEGORY = 0b01
WALL_CATEGORY = 0b10


def _address(cdata: object) -> int:
    return int(_ffi.cast("uintptr_t", cdata))


class Scatter(NamedTuple):
    """Robots and their batch slots: robot `robots_in[k]` is row `slots[k]` of the batch buffers
    (`in_order`: robot i is row i, no scatter needed)."""

    in_order: bool
    robots_in: np.ndarray
    slots: np.ndarray
    positions_in: np.ndarray
    velocities_in: np.ndarray


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
        n = len(self.bodies)
        self._pos = np.zeros((n, 2))  # last known centres (a body off the floor keeps its own)
        # Batch buffers over numpy memory: pymunk reads velocities from and writes positions into
        # them directly. One row per body the batch visits (the robots in the space, plus the
        # static body of the walls); room for one more row so pymunk never has to grow them.
        self._positions_in = np.zeros((n + 2, 2))
        self._velocities_in = np.zeros((n + 2, 2))
        self._velocity_out = np.zeros((n, 2))
        self.version = 0  # bumped whenever robots' slots or the arrays below change
        self._bind_batch()
        self._reindex()

    def _bind_batch(self) -> None:
        """Prepare the two batch calls once. They are `pymunk.batch.get_space_bodies` and
        `set_space_bodies` (pymunk 7) with the C argument block built here instead of on every
        call, which was most of their cost."""
        self._get = pymunk.batch.Buffer()
        self._get.set_float_buf(self._positions_in.reshape(-1))
        self._set = pymunk.batch.Buffer()
        self._get_args = _ffi.new("pmBatchedData *")
        self._get_args.fields = pymunk.batch.BodyFields.POSITION.value
        self._get_args.floatArray = self._get._float_arr
        self._get_args.intArray = self._get._int_arr
        self._set_args = _ffi.new("pmBatchedData *")
        self._set_args.fields = pymunk.batch.BodyFields.VELOCITY.value
        self._set_args.intArray = self._set._int_arr
        self._space_ptr = self.space._space
        # what the compiled tick needs to make the same calls, at the indices it reads them
        calls = {
            C_STEP: _ffi.addressof(_lib, "cpSpaceStep"),
            C_EACH_BODY: _ffi.addressof(_lib, "cpSpaceEachBody"),
            C_SPACE: self._space_ptr,
            C_SET_VISIT: _SET_BODIES,
            C_SET_DATA: self._set_args,
            C_SET_FLOATS: self._set._float_arr,
            C_GET_VISIT: _GET_BODIES,
            C_GET_DATA: self._get_args,
            C_GET_FLOATS: self._get._float_arr,
        }
        self.c_calls = np.array([_address(calls[k]) for k in sorted(calls)], dtype=np.int64)

    def __getstate__(self) -> dict[str, object]:
        # Not `copy` nor `pickle`: pymunk's copy of a space keeps positions, velocities and cached
        # contacts, but not the bodies' bias velocities (the push that separates two robots that
        # touched in the last step) nor its spatial index, whose order decides in which order
        # contacts are solved; a copy drifts from the original at the next contact. An env
        # copies its arena by replaying the episode instead (tavc_env.env, "Copying").
        raise ValueError(
            "a physics World cannot be copied or pickled exactly (pymunk does not carry the bias "
            "velocities of bodies that touched, nor the order of contacts); allowed: copy the env "
            "(copy.deepcopy(env) or pickle), which rebuilds its arena by replaying its episode"
        )

    def __del__(self) -> None:
        # A World dies by reference count (an env's reset replaces it), and its space's C memory
        # with it, at once; pymunk's bodies and shapes live in reference cycles and wait for the
        # garbage collector. pymunk frees a space by walking the bodies still in it, and a
        # collection during that walk (any allocation may start one) frees bodies the walk is
        # about to visit: a crash (a use after free in cpSpaceRemoveBody, found by
        # tests/fuzz). So everything leaves the space first, and the walk finds nothing.
        try:
            space = self.space
            robots = [i for i in range(len(self.bodies)) if self.in_space[i]]
            space.remove(*self.walls, *(self.shapes[i] for i in robots))
            space.remove(*(self.bodies[i] for i in robots))
            # pymunk adds its static body (the walls') to the C space only: take it out there
            _lib.cpSpaceRemoveBody(self._space_ptr, space.static_body._body)
        except Exception:  # a World that failed half-way through __init__, interpreter exit
            pass

    def _reindex(self) -> None:
        """Find each robot's slot in the batch order (after bodies enter or leave the space)."""
        self._get.clear()
        pymunk.batch.get_space_bodies(self.space, pymunk.batch.BodyFields.BODY_ID, self._get)
        ids = np.frombuffer(self._get.int_buf(), dtype=np.uintp)
        slot_of_id = {int(body_id): k for k, body_id in enumerate(ids)}
        self._robots_in = np.flatnonzero(self.in_space)
        self._slots = np.array(
            [slot_of_id[self.bodies[i].id] for i in self._robots_in], dtype=np.intp
        )
        self._visited = len(ids)
        # the common case, every robot in the space in index order: plain slices, no scatter
        self._in_order = len(self._robots_in) == self.n and bool(
            np.all(self._slots == np.arange(self.n))
        )
        self._velocities_in[:] = 0.0  # the static body (and robots off the floor) stay still
        self._set.set_float_buf(self._velocities_in[: self._visited].reshape(-1))
        self._set_args.floatArray = self._set._float_arr
        for i, body in enumerate(self.bodies):
            self._pos[i] = tuple(body.position)
        if self._in_order:
            self._positions_in[: self.n] = self._pos
        # `pos`: the robots' centres after the last `sync_positions`, always the same array
        # until the next reindex (a view of pymunk's output when no scatter is needed)
        self.pos = self._positions_in[: self.n] if self._in_order else self._pos
        self.velocity_out = self._velocities_in[: self.n] if self._in_order else self._velocity_out
        self.version += 1

    @property
    def n(self) -> int:
        return len(self.bodies)

    def scatter(self) -> Scatter:
        """How `push_velocities` and `sync_positions` map robots to batch slots, for the compiled
        tick (valid until `version` changes)."""
        return Scatter(
            self._in_order, self._robots_in, self._slots, self._positions_in, self._velocities_in
        )

    def place(self, positions: np.ndarray) -> None:
        """Teleport every robot (used at reset) and stop it."""
        for body, (x, y) in zip(self.bodies, positions):
            body.position = (float(x), float(y))
            body.velocity = (0.0, 0.0)
        for body in self.bodies:
            self.space.reindex_shapes_for_body(body)
        self._reindex()

    def sync_positions(self) -> None:
        """Read every robot's centre from pymunk into `pos`."""
        self._get._float_arr.num = 0
        _lib.cpSpaceEachBody(self._space_ptr, _GET_BODIES, self._get_args)
        if not self._in_order:
            self._pos[self._robots_in] = self._positions_in[self._slots]

    def positions(self) -> np.ndarray:
        """Robot centres, shape (n, 2) (a robot off the floor: where it left); a copy."""
        self.sync_positions()
        return self.pos.copy()

    def velocities(self) -> np.ndarray:
        """Robot velocities, shape (n, 2)."""
        return np.array([tuple(b.velocity) for b in self.bodies], dtype=np.float64)

    def push_velocities(self) -> None:
        """Give every robot on the floor the velocity written into `velocity_out`."""
        if not self._in_order:
            self._velocities_in[self._slots] = self._velocity_out[self._robots_in]
        floats = self._set._float_arr
        count = floats.num
        floats.num = 0  # the iterator reads from the start, advancing `num`
        _lib.cpSpaceEachBody(self._space_ptr, _SET_BODIES, self._set_args)
        floats.num = count

    def set_velocities(self, velocities: np.ndarray) -> None:
        """Set every robot's velocity (rows of robots off the floor are ignored)."""
        self.velocity_out[:] = velocities
        self.push_velocities()

    def step(self, dt: float) -> None:
        self.space.step(dt)

    def remove_robot(self, i: int) -> None:
        """Take robot i off the floor (a broken robot is carried out for repair)."""
        if self.in_space[i]:
            self.bodies[i].velocity = (0.0, 0.0)
            self.space.remove(self.bodies[i], self.shapes[i])
            self.in_space[i] = False
            self._reindex()

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
        self._reindex()

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
