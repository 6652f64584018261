"""What one trial recorded (`TrialResult`): a plain, JSON-serialisable dataclass, saved and loaded
with a schema version and a checksum. Beside the runner that fills it (`runner.run_trial`, which
also names it), so that readers of saved trials (packs, sweeps) need not import the runner.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tavc_agents.experiments.files import CorruptFileError, read_record, write_record


@dataclass
class TrialResult:
    """Everything one trial recorded (times in simulated seconds)."""

    seed: int
    label: str
    env_kwargs: dict[str, Any]
    agents: list[str]
    speed_classes: list[str]
    speeds: list[float]
    values: list[float]
    convergence_s: float
    measured_s: float
    end_s: float
    initial_circuits: list[int]
    changes: list[tuple[float, int, int]] = field(default_factory=list)
    delivery_time_s: list[float] = field(default_factory=list)
    delivery_robot: list[int] = field(default_factory=list)
    delivery_circuit: list[int] = field(default_factory=list)
    delivery_task_time_s: list[float] = field(default_factory=list)
    delivery_value: list[float] = field(default_factory=list)  # w of the circuit when delivered
    events: list[tuple[float, str, Any]] = field(default_factory=list)  # (applied at, kind, arg)
    q_snapshots: list[dict[str, Any]] = field(default_factory=list)
    learner_stats: dict[str, dict[str, Any]] = field(default_factory=dict)
    capped_steps: int = 0
    escapes: int = 0  # stuck robots' escape manoeuvres (navigation.STUCK_PATIENCE_S)
    jams: int = 0  # jams the env's detector found (`TavcArenaEnv.jams`)
    jammed_s: float = 0.0  # simulated time spent jammed
    steps: int = 0
    wall_s: float = 0.0
    spec: dict[str, Any] = field(default_factory=dict)  # the sweep's TrialSpec, when run by one

    @property
    def measured_window(self) -> tuple[float, float]:
        return self.convergence_s, self.convergence_s + self.measured_s

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TrialResult:
        d = dict(data)
        d["changes"] = [tuple(c) for c in d.get("changes", [])]
        d["events"] = [tuple(e) for e in d.get("events", [])]
        return cls(**d)

    def save(self, path: str | Path) -> None:
        """Write atomically with a schema version and a checksum (a partial file never replaces
        a finished one; see `tavc_agents.experiments.files`)."""
        write_record(path, self.to_dict())

    @classmethod
    def load(cls, path: str | Path) -> TrialResult:
        """A saved trial, checked: a corrupt or edited file raises `CorruptFileError` naming it."""
        data = read_record(path)
        try:
            return cls.from_dict(data)
        except TypeError as error:
            raise CorruptFileError(f"{path} is not a saved trial ({error})") from None
