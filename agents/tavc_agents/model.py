"""The TAVC model of Dahl, Mataric & Sukhatme (DARS 2004, section 3), made computable and measurable.

A group J of robots serving circuit i completes tasks at a frequency c_{i,J} (tasks per second).
Robots of one speed class are interchangeable, so a group is a composition: how many robots of each
class. The value of a slot -- one more robot of class j joining group J on circuit i -- is the
paper's Equation 1,

    s_{i,J,j} = w_i (c_{i,J+j} - c_{i,J}),

the team's value rate under an allocation (one group per circuit) is sum_i w_i c_{i,J_i}, and the
model-optimal allocation maximises it. `CompletionModel.optimum` finds it by exhaustive search over
every split of the team (a few thousand allocations for three circuits and nine robots).

`estimate_model` of `benchmarks/arena_runs.py` measures c by simulation: each composition serves
each circuit alone, as fixed allocations, and `model_from_runs` turns those runs into a model. The
model therefore assumes that circuits do not slow each other down and that moving between circuits
is free; the `tavc_model` study checks its predictions against the full arena.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tavc_env import ArenaConfig, Robot, metrics
from tavc_env.safe_files import MIB, kind_of, read_json
from tavc_env.validation import is_number, require

REFERENCE_MODELS = Path(__file__).parent / "data" / "models"
MODEL_MAX_BYTES = 16 * MIB  # the largest shipped model (large_team.json) is 46 KiB
"""The measured models the package ships, `<preset>.json` each: what the model-based allocators
(`static`, `greedy`, `auction`) use by default. They are package data, so an installed wheel has
them; the `tavc_model` study writes them (`--update-reference`), and this is their only copy."""

Group = tuple[int, ...]  # robots per speed class on one circuit
EXHAUSTIVE_LIMIT = 200_000
"""`CompletionModel.optimum` searches exhaustively up to this many allocations (the presets of
two and three circuits have at most a few thousand), by circuit beyond."""
Allocation = tuple[Group, ...]  # one group per circuit


@dataclass(frozen=True)
class SpeedClasses:
    """A team's speed classes, fastest first: labels, a representative robot, and each robot's
    class index."""

    labels: tuple[str, ...]
    robots: tuple[Robot, ...]
    of_robot: tuple[int, ...]

    @property
    def team(self) -> Group:
        return tuple(self.of_robot.count(k) for k in range(len(self.labels)))

    @classmethod
    def of(cls, config: ArenaConfig) -> SpeedClasses:
        """Group `config.robots` by `speed_class` label (robots of a label must share a speed)."""
        speeds: dict[str, float] = {}
        for i, robot in enumerate(config.robots):
            known = speeds.setdefault(robot.speed_class, robot.speed)
            require(
                known == robot.speed,
                f"robots[{i}].speed",
                robot.speed,
                f"{known} like the other {robot.speed_class!r} robots (a class is one speed)",
            )
        labels = tuple(sorted(speeds, key=lambda label: (-speeds[label], label)))
        robots = tuple(Robot(speeds[label], label) for label in labels)
        of_robot = tuple(labels.index(r.speed_class) for r in config.robots)
        return cls(labels, robots, of_robot)


@dataclass(frozen=True, eq=False)
class CompletionModel:
    """Task-completion frequencies c_{i,J} of every group J on every circuit i, and the circuits'
    values w_i.

    `rates[i][J]` is c_{i,J} in tasks per second, indexed by circuit then by the count of each
    class (shape `(n_circuits, team[0] + 1, team[1] + 1, ...)`); the empty group completes nothing.
    `rates_se`, if given, holds the standard errors of the estimates.
    """

    classes: tuple[str, ...]
    team: Group
    values: tuple[float, ...]
    rates: np.ndarray
    rates_se: np.ndarray | None = field(default=None)

    def __post_init__(self) -> None:
        object.__setattr__(self, "classes", tuple(self.classes))
        object.__setattr__(self, "team", tuple(int(n) for n in self.team))
        object.__setattr__(self, "values", tuple(float(w) for w in self.values))
        require(len(self.classes) >= 1, "classes", self.classes, "at least one speed class")
        require(
            len(self.team) == len(self.classes) and all(n >= 0 for n in self.team),
            "team",
            self.team,
            f"{len(self.classes)} robot counts >= 0, one per class {list(self.classes)}",
        )
        require(
            len(self.values) >= 1 and all(is_number(w) and w > 0 for w in self.values),
            "values",
            self.values,
            "one value > 0 per circuit",
        )
        rates = np.asarray(self.rates, dtype=float)
        shape = (len(self.values), *(n + 1 for n in self.team))
        require(rates.shape == shape, "rates.shape", rates.shape, f"{shape} (circuit, counts...)")
        bad = rates[~(np.isfinite(rates) & (rates >= 0))]
        require(bad.size == 0, "rates", bad[:1].tolist(), "finite frequencies >= 0")
        empty = rates.reshape(len(self.values), -1)[:, 0]  # every class count 0
        require(
            bool(np.all(empty == 0)), "rates of the empty group", empty.tolist(), "0 (no robot)"
        )
        rates.setflags(write=False)
        object.__setattr__(self, "rates", rates)
        if self.rates_se is not None:
            se = np.asarray(self.rates_se, dtype=float)
            require(se.shape == shape, "rates_se.shape", se.shape, f"{shape} like rates")
            se.setflags(write=False)
            object.__setattr__(self, "rates_se", se)

    # -- shape ----------------------------------------------------------------------------------
    @property
    def n_circuits(self) -> int:
        return len(self.values)

    @property
    def n_robots(self) -> int:
        return sum(self.team)

    # -- Equation 1 and the team's value --------------------------------------------------------
    def rate(self, circuit: int, group: Sequence[int]) -> float:
        """c_{i,J}: tasks per second of `group` on `circuit`."""
        index = (circuit, *self._group(group))
        return float(self.rates[index])

    def slot_value(self, circuit: int, group: Sequence[int], cls: int) -> float:
        """s_{i,J,j} = w_i (c_{i,J+j} - c_{i,J}) (Equation 1), in value per second."""
        joined = list(self._group(group))
        require(0 <= cls < len(self.classes), "cls", cls, f"a class in [0, {len(self.classes)})")
        joined[cls] += 1
        return self.values[circuit] * (self.rate(circuit, joined) - self.rate(circuit, group))

    def value_rate(self, allocation: Allocation) -> float:
        """sum_i w_i c_{i,J_i}: value delivered per second by the whole team."""
        self._check_allocation(allocation)
        return sum(w * self.rate(i, g) for i, (w, g) in enumerate(zip(self.values, allocation)))

    def performance(self, allocation: Allocation) -> float:
        """The paper's measure: delivered value (w_i / max w per delivery) per robot per 10 s."""
        robots = sum(sum(g) for g in allocation)
        return self.value_rate(allocation) / max(self.values) / max(robots, 1) * 10.0

    def mean_performance(
        self,
        initial: Sequence[int],
        changes: Sequence[tuple[float, int, int]],
        classes: SpeedClasses,
        t0: float,
        t1: float,
    ) -> float:
        """`performance` of the allocation a team held over `[t0, t1)` (an allocation timeline:
        initial circuits and time-ordered changes), time-weighted. Every robot counts, so use it
        on windows without breakdowns."""
        durations, states = metrics.allocation_segments(initial, changes, t0, t1)
        values = np.array(
            [self.performance(allocation_of(row, classes, self.n_circuits)) for row in states]
        )
        return float((durations * values).sum() / durations.sum())

    # -- search ---------------------------------------------------------------------------------
    def allocations(self, team: Sequence[int] | None = None) -> Iterator[Allocation]:
        """Every way to split `team` (default: the whole team) over the circuits."""
        counts = self._team(team)
        per_class = [list(_splits(n, self.n_circuits)) for n in counts]
        for choice in itertools.product(*per_class):
            yield tuple(tuple(split[i] for split in choice) for i in range(self.n_circuits))

    def ranked(self, team: Sequence[int] | None = None) -> list[tuple[float, Allocation]]:
        """Every allocation of `team` with its value rate, best first (ties: lexicographic)."""
        scored = [(self.value_rate(a), a) for a in self.allocations(team)]
        return sorted(scored, key=lambda item: (-item[0], item[1]))

    def optimum(self, team: Sequence[int] | None = None) -> Allocation:
        """The model-optimal allocation of `team` (default: the whole team): by exhaustive search
        (`ranked`, ties broken lexicographically) up to `EXHAUSTIVE_LIMIT` allocations, beyond
        that by dynamic programming over the circuits (exact too: the value is a sum over
        circuits; ties broken towards the first group tried, the largest on circuit 0)."""
        counts = self._team(team)
        if self.n_allocations(counts) <= EXHAUSTIVE_LIMIT:
            return self.ranked(counts)[0][1]
        return self._optimum_by_circuit(counts)

    def n_allocations(self, team: Sequence[int] | None = None) -> int:
        """How many ways there are to split `team` (default: the whole team) over the circuits."""
        m = self.n_circuits
        return math.prod(math.comb(n + m - 1, m - 1) for n in self._team(team))

    def ranked_if_few(self) -> list[tuple[float, Allocation]] | None:
        """`ranked()` for the whole team, or None beyond `EXHAUSTIVE_LIMIT` allocations."""
        return self.ranked() if self.n_allocations() <= EXHAUSTIVE_LIMIT else None

    def _optimum_by_circuit(self, team: Group) -> Allocation:
        # best[i][r]: the best value of circuits i.. serving the robots r (counts per class)
        remaining = list(itertools.product(*(range(n + 1) for n in team)))
        m = self.n_circuits
        best: list[dict[Group, tuple[float, Allocation]]] = [{} for _ in range(m + 1)]
        best[m] = {r: (0.0 if sum(r) == 0 else -math.inf, ()) for r in remaining}
        for i in range(m - 1, -1, -1):
            w = self.values[i]
            for r in remaining:
                top: tuple[float, Allocation] = (-math.inf, ())
                for g in itertools.product(*(range(n, -1, -1) for n in r)):
                    rest = tuple(a - b for a, b in zip(r, g))
                    value, tail = best[i + 1][rest]
                    value += w * self.rate(i, g) if sum(g) else 0.0
                    if value > top[0]:
                        top = (value, (g, *tail))
                best[i][r] = top
        return best[0][team][1]

    def neighbours(self, allocation: Allocation) -> list[Allocation]:
        """Allocations one move away: one robot of one class moved to another circuit."""
        self._check_allocation(allocation)
        found = []
        for src, dst in itertools.permutations(range(self.n_circuits), 2):
            for k in range(len(self.classes)):
                if allocation[src][k] == 0:
                    continue
                groups = [list(g) for g in allocation]
                groups[src][k] -= 1
                groups[dst][k] += 1
                found.append(tuple(tuple(g) for g in groups))
        return found

    def with_values(self, values: Sequence[float]) -> CompletionModel:
        """The same frequencies under other circuit values (e.g. after a priority change)."""
        return CompletionModel(self.classes, self.team, tuple(values), self.rates, self.rates_se)

    def slot_table(self) -> list[dict[str, Any]]:
        """Every slot value s_{i,J,j}, one row per circuit, group and joining class."""
        rows = []
        for i in range(self.n_circuits):
            for group in itertools.product(*(range(n + 1) for n in self.team)):
                for k, label in enumerate(self.classes):
                    if group[k] < self.team[k]:
                        rows.append(
                            {
                                "circuit": i,
                                "group": self.describe(group),
                                "joining": label,
                                "c_group_per_h": 3600 * self.rate(i, group),
                                "slot_value_per_h": 3600 * self.slot_value(i, group, k),
                            }
                        )
        return rows

    def describe(self, group: Sequence[int]) -> str:
        """A group as text, e.g. `2 fast + 1 slow` (or `none`)."""
        parts = [f"{n} {label}" for n, label in zip(group, self.classes) if n]
        return " + ".join(parts) if parts else "none"

    # -- storage --------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "classes": list(self.classes),
            "team": list(self.team),
            "values": list(self.values),
            "rates": self.rates.tolist(),
        }
        if self.rates_se is not None:
            data["rates_se"] = self.rates_se.tolist()
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> CompletionModel:
        allowed = {"classes", "team", "values", "rates", "rates_se"}
        unknown = sorted(set(data) - allowed)
        require(not unknown, "model keys", unknown, f"only {sorted(allowed)}")
        missing = sorted({"classes", "team", "values", "rates"} - set(data))
        require(not missing, "model keys missing", missing, "classes, team, values and rates")
        se = data.get("rates_se")
        return cls(
            tuple(data["classes"]),
            tuple(data["team"]),
            tuple(data["values"]),
            np.asarray(data["rates"], dtype=float),
            None if se is None else np.asarray(se, dtype=float),
        )

    @classmethod
    def load(cls, path: str | Path) -> CompletionModel:
        """The model saved at `path` (a model.json), read safely (`read_model`)."""
        data = read_model(path)
        require(isinstance(data, Mapping), f"model in {path}", type(data).__name__, "a JSON object")
        return cls.from_dict(data)

    def check_team(self, classes: SpeedClasses) -> None:
        """Raise unless `classes` (of an arena's robots) is the team this model describes."""
        require(
            classes.labels == self.classes and classes.team == self.team,
            "arena team",
            dict(zip(classes.labels, classes.team)),
            f"the model's team {dict(zip(self.classes, self.team))}",
        )

    # -- helpers --------------------------------------------------------------------------------
    def _group(self, group: Sequence[int]) -> Group:
        g = tuple(int(n) for n in group)
        ok = len(g) == len(self.team) and all(0 <= n <= m for n, m in zip(g, self.team))
        require(ok, "group", list(group), f"counts per class within the team {list(self.team)}")
        return g

    def _team(self, team: Sequence[int] | None) -> Group:
        return self.team if team is None else self._group(team)

    def _check_allocation(self, allocation: Allocation) -> None:
        require(
            len(allocation) == self.n_circuits,
            "allocation",
            allocation,
            f"one group per circuit ({self.n_circuits})",
        )
        for g in allocation:
            require(
                len(g) == len(self.team),
                "allocation group",
                g,
                f"one count per class {list(self.classes)}",
            )
        totals = [sum(g[k] for g in allocation) for k in range(len(self.team))]
        require(
            all(t <= m for t, m in zip(totals, self.team)),
            "allocation",
            allocation,
            f"at most the team {list(self.team)} in total",
        )
        for g in allocation:
            self._group(g)


def model_path(preset: str, path: Path | None = None) -> Path:
    """`path`, or the shipped model of `preset` (which may not exist: see `missing_model`)."""
    return path if path is not None else REFERENCE_MODELS / f"{preset}.json"


def missing_model(preset: str, path: Path | None = None) -> str | None:
    """Why the model at `path` (default: the shipped one of `preset`) cannot be used, or None."""
    where = model_path(preset, path)
    if where.is_file():
        return None
    if path is not None:
        if not os.path.lexists(where):
            return f"{where} is missing"
        try:
            what = kind_of(where.stat().st_mode)
        except OSError:  # a dangling link
            return f"{where} is a symbolic link to nothing"
        return f"{where} is {what}, not a regular file"
    shipped = sorted(p.stem for p in REFERENCE_MODELS.glob("*.json"))
    return (
        f"no TAVC model of {preset!r} ships with the package (it has those of {shipped}); "
        f"measure one with `python benchmarks/tavc_model.py --preset {preset}` and pass its model.json"
    )


def read_model(path: str | Path) -> Any:
    """The JSON of the model file `path`, read safely (a regular file of at most
    `MODEL_MAX_BYTES`, finite numbers; `tavc_env.safe_files`): a ValueError naming it otherwise."""
    return read_json(path, MODEL_MAX_BYTES, "TAVC model (model.json)")


def load_model(preset: str, path: Path | None = None) -> CompletionModel:
    """The model at `path` (default: the shipped model of `preset`)."""
    return CompletionModel.load(model_path(preset, path))


def as_model(model: CompletionModel | Mapping[str, Any]) -> CompletionModel:
    """`model` itself, or the model its dict (`CompletionModel.to_dict`, a model.json) describes."""
    if isinstance(model, CompletionModel):
        return model
    require(isinstance(model, Mapping), "model", type(model).__name__, "a CompletionModel or dict")
    return CompletionModel.from_dict(model)


def _splits(n: int, parts: int) -> Iterator[tuple[int, ...]]:
    """Every way to write n as an ordered sum of `parts` counts >= 0."""
    if parts == 1:
        yield (n,)
        return
    for first in range(n, -1, -1):
        for rest in _splits(n - first, parts - 1):
            yield (first, *rest)


def allocation_of(circuits: Sequence[int], classes: SpeedClasses, n_circuits: int) -> Allocation:
    """The groups per circuit when robot r serves `circuits[r]`."""
    groups = [[0] * len(classes.labels) for _ in range(n_circuits)]
    for circuit, k in zip(circuits, classes.of_robot):
        groups[int(circuit)][k] += 1
    return tuple(tuple(g) for g in groups)


def fs_label(allocation: Allocation, circuit: int = 0) -> str:
    """The paper's `f:s` notation generalised: robots of each class on `circuit`, joined by ':'."""
    return ":".join(str(n) for n in allocation[circuit])


def robot_circuits(allocation: Allocation, classes: SpeedClasses) -> list[int]:
    """One circuit per robot realising `allocation`: within a class, robots in index order fill
    circuit 0's places first, then circuit 1's, and so on."""
    remaining = [list(g) for g in allocation]
    circuits = []
    for i, k in enumerate(classes.of_robot):
        target = next((c for c, g in enumerate(remaining) if g[k] > 0), None)
        require(target is not None, f"allocation for robot {i}", allocation, "a place per robot")
        assert target is not None
        remaining[target][k] -= 1
        circuits.append(target)
    require(
        all(n == 0 for g in remaining for n in g),
        "allocation",
        allocation,
        f"exactly the team {list(classes.team)}",
    )
    return circuits


def model_from_runs(
    config: ArenaConfig, runs: Sequence[tuple[int, Group, float]]
) -> CompletionModel:
    """A model from measured runs `(circuit, group, tasks per second)`: the mean over repeats and
    its standard error (0 with one repeat)."""
    classes = SpeedClasses.of(config)
    shape = (config.n_circuits, *(n + 1 for n in classes.team))
    samples: dict[tuple[int, ...], list[float]] = {}
    for circuit, group, rate in runs:
        samples.setdefault((circuit, *group), []).append(rate)
    rates = np.zeros(shape)
    se = np.zeros(shape)
    for index in itertools.product(*(range(n) for n in shape)):
        if sum(index[1:]) == 0:
            continue
        values = samples.get(index)
        require(
            values is not None,
            "runs",
            f"no run of group {index[1:]} on circuit {index[0]}",
            "a run of every non-empty group on every circuit",
        )
        assert values is not None
        rates[index] = float(np.mean(values))
        se[index] = float(np.std(values, ddof=1) / np.sqrt(len(values))) if len(values) > 1 else 0.0
    return CompletionModel(
        classes.labels, classes.team, tuple(c.value for c in config.circuits), rates, se
    )
