"""What a robot observes: the paper's one-hot, the same with an agent id, or a rich view for deep RL.

The paper's premise is that a robot does not know its own speed. Each mode says what it reveals:

| mode | vector | what it reveals |
|---|---|---|
| `paper` (default) | one-hot of the robot's last circuit (m) | nothing beyond the paper's state; speed only through rewards `w / t` |
| `paper_id` | `paper` + one-hot of the robot's index (n) | which robot it is, so a network shared by all robots can tell them apart; in the shipped presets the index also encodes the speed class (robots 0-2 are the fast ones in `dahl2004`), so a shared network can learn speed from it |
| `rich` | `paper_id` + own pose, velocity, phase, time since the last decision, own last task time per circuit, robots serving each circuit, circuit values | the robot's own speed (velocity, task times), where it is and how crowded each circuit is; for deep RL that is not bound by the paper's premise |

All values are float32 in [0, 1] (heading and velocity components in [-1, 1]). Times are divided by
`TIME_SCALE_S` and clipped to 1. Velocity is divided by the fastest robot's top speed in the team,
so a fast robot moving freely reads about 1 and a slow one less. The twin (`tavc_env.twin`) has no
positions: it offers `paper` and `paper_id` only.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from tavc_env.config import ArenaConfig
from tavc_env.engine.tasks import Phase
from tavc_env.validation import require

OBSERVATION_MODES = ("paper", "paper_id", "rich")
OBSERVATION_FORMATS = ("dict", "box")
TIME_SCALE_S = 600.0  # the default event-driven step cap: longer waits all read 1
N_PHASES = len(Phase)


def check_observation_args(mode: object, fmt: object) -> None:
    """Raise a ValueError naming a bad observation mode or format and what is allowed."""
    require(
        mode in OBSERVATION_MODES, "observation_mode", mode, f"one of {list(OBSERVATION_MODES)}"
    )
    require(
        fmt in OBSERVATION_FORMATS,
        "observation_format",
        fmt,
        "'dict' (observation + action_mask) or 'box' (the observation vector alone; the mask "
        "is then in each info's 'action_mask')",
    )


def feature_names(config: ArenaConfig, mode: str) -> list[str]:
    """The name of each entry of the observation vector in `mode`, in order."""
    n, m = config.n_robots, config.n_circuits
    names = [f"last_circuit_{c}" for c in range(m)]
    if mode in ("paper_id", "rich"):
        names += [f"agent_id_{i}" for i in range(n)]
    if mode == "rich":
        names += ["x", "y", "cos_heading", "sin_heading", "vx", "vy"]
        names += [f"phase_{p.name.lower()}" for p in Phase]
        names += ["time_since_decision"]
        names += [f"last_task_time_circuit_{c}" for c in range(m)]
        names += [f"robots_on_circuit_{c}" for c in range(m)]
        names += [f"value_circuit_{c}" for c in range(m)]
    return names


class ObservationBuilder:
    """Builds every robot's observation vector in one mode; its space is built once."""

    def __init__(self, config: ArenaConfig, mode: str) -> None:
        self.config = config
        self.mode = mode
        self.names = feature_names(config, mode)
        n, m = config.n_robots, config.n_circuits
        size = len(self.names)
        low = np.zeros(size, np.float32)
        if mode == "rich":
            pose = m + n + 2  # cos, sin heading and vx, vy may be negative
            low[pose : pose + 4] = -1.0
        self.space = spaces.Box(low, np.ones(size, np.float32), (size,), np.float32)
        # The paper's modes take one of m values per robot: rows of one shared read-only table
        # (robot or 0, circuit), not two new arrays per agent per step (that dominated steps
        # with hundreds of robots).
        eye = np.eye(m, dtype=np.float32)
        ids = np.eye(n, dtype=np.float32)
        per_robot = mode != "paper"
        self._table = frozen(
            np.array(
                [
                    [np.concatenate([eye[c], ids[i]]) if per_robot else eye[c] for c in range(m)]
                    for i in range(n if per_robot else 1)
                ]
            )
        )
        self._row_of = np.arange(n) if per_robot else np.zeros(n, np.int64)
        self._rows = [list(rows) for rows in self._table]  # read-only views, made once
        self._v_ref = max(r.speed for r in config.robots)

    def build(self, sim: Any, last_task_s: np.ndarray) -> list[np.ndarray]:
        """Every robot's observation now, one vector per robot (read-only in the paper's modes).
        `last_task_s[i, c]`: robot i's last task time on circuit c in seconds (NaN: none yet)."""
        if self.mode == "rich":
            return list(self._rich(sim, last_task_s))
        circuits = _plain(sim.tasks.circuit)
        if self.mode == "paper":
            row = self._rows[0]
            return [row[c] for c in circuits]
        return [rows[c] for rows, c in zip(self._rows, circuits)]

    def stacked(
        self, sims: list[Any], last_task_s: list[np.ndarray], circuit: np.ndarray
    ) -> np.ndarray:
        """The observations of several arenas now, `(K, n, k)` float32 (the rows of `build`):
        arena k's engine `sims[k]`, its last task times `last_task_s[k]` and circuits
        `circuit[k]`."""
        if self.mode == "rich":
            return np.array([self._rich(sim, last) for sim, last in zip(sims, last_task_s)])
        rows: np.ndarray = self._table[self._row_of, circuit]
        return rows

    def _rich(self, sim: Any, last_task_s: np.ndarray) -> np.ndarray:
        cfg = self.config
        n, m = cfg.n_robots, cfg.n_circuits
        tasks = sim.tasks
        out = np.zeros((n, len(self.names)), np.float32)
        rows = np.arange(n)
        out[rows, tasks.circuit] = 1.0
        out[rows, m + rows] = 1.0
        k = m + n
        out[:, k : k + 6] = pose_features(sim, cfg, self._v_ref)
        k += 6
        out[rows, k + tasks.phase] = 1.0
        k += N_PHASES
        elapsed = sim.time_s - tasks.decision_time
        out[:, k] = np.clip(elapsed / TIME_SCALE_S, 0.0, 1.0)
        k += 1
        out[:, k : k + m] = np.clip(np.nan_to_num(last_task_s, nan=0.0) / TIME_SCALE_S, 0.0, 1.0)
        k += m
        serving = (tasks.phase == int(Phase.TO_SOURCE)) | (tasks.phase == int(Phase.TO_SINK))
        counts = np.bincount(tasks.circuit[serving], minlength=m)[:m]
        out[:, k : k + m] = counts / n
        k += m
        values = np.asarray(tasks.values, dtype=float)
        out[:, k : k + m] = values / values.max()
        return out


def pose_features(sim: Any, config: ArenaConfig, speed: float | np.ndarray) -> np.ndarray:
    """Per robot `[x/W, y/H, cos h, sin h, vx/speed, vy/speed]`: positions clipped to [0, 1],
    velocity components to [-1, 1] (contacts can briefly push a robot faster). `speed`: one
    reference speed, or a column of each robot's own."""
    pos = sim.positions()
    out = np.empty((len(pos), 6), np.float32)
    out[:, 0] = np.clip(pos[:, 0] / config.width, 0.0, 1.0)
    out[:, 1] = np.clip(pos[:, 1] / config.height, 0.0, 1.0)
    out[:, 2] = np.cos(sim.heading)
    out[:, 3] = np.sin(sim.heading)
    out[:, 4:6] = np.clip(sim.world.velocities() / speed, -1.0, 1.0)
    return out


def _plain(values: Any) -> list[Any]:
    """Per-robot values, an array (the physics) or a list (the twin), as a list."""
    return values.tolist() if isinstance(values, np.ndarray) else values


def frozen(array: np.ndarray) -> np.ndarray:
    """A read-only copy of `array` (shared between observations, so nobody may change it)."""
    array = array.copy()
    array.setflags(write=False)
    return array
