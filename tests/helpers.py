"""Plain helpers shared by the test modules (fixtures wrapping them live in conftest.py).

* `run_env(env, steps, policy=..., seed=...)` drives an env and records every step;
* `lockstep(env_a, env_b, steps, ...)` drives two envs with the same actions and asserts that they
  return identical results at every step;
* `strict_warnings()` fails on any warning except the two inherent PettingZoo advisories;
* `record_crowd_run()` records, tick by tick, all six `dahl2004` robots serving one circuit.
"""

from __future__ import annotations

import contextlib
import importlib
import re
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence

import tavc_env
from tavc_env import completed_task_s

# Advisories PettingZoo's checkers give for any Dict observation space. They are inherent to the
# design (DESIGN.md section 2 fixes the observation as Dict(observation, action_mask)); everything
# else, in particular "Live agent was not given ...", "... was dead last turn" and "No agents
# present ...", is a failure.
TOLERATED_WARNINGS = (
    re.compile(r"probably should be gymnasium\.spaces\.box"),
    re.compile(r"Observation is not a NumPy array"),
)

Policy = Callable[[dict[str, Any], dict[str, Any], np.random.Generator], dict[str, Any]]

REQUIRED_INFO_KEYS = {
    "action_required",
    "circuit",
    "phase",
    "broken",
    "task_time_s",
    "elapsed_s",
    "sim_time_s",
}

# Configurations every PettingZoo checker runs over (keyword arguments of `tavc_env.parallel_env`).
CONFIGS: dict[str, dict[str, Any]] = {
    "dahl2004": {"preset": "dahl2004"},
    "dahl2004_homogeneous": {"preset": "dahl2004_homogeneous"},
    # Twelve robots need a 21 m arena: every waiting line must hold the 11 others (checked by
    # the configuration's validation), and in 18 m the middle lines have room for only 10.
    "three_circuits_12_robots": {
        "width": 21.0,
        "circuits": tavc_env.lane_circuits(3, width=21.0, values=(2200.0, 2000.0, 1800.0)),
        "speeds": [0.3] * 6 + [0.2] * 6,
    },
    "fixed_interval_30s": {"decision_interval_s": 30.0},
}
# Every observation mode and format but the default (which CONFIGS run), for the checkers.
OBSERVATION_CONFIGS: dict[str, dict[str, Any]] = {
    "paper_id_observations": {"observation_mode": "paper_id"},
    "rich_observations": {"observation_mode": "rich"},
    "box_observations": {"observation_format": "box"},
    "rich_box_observations": {"observation_mode": "rich", "observation_format": "box"},
    "rich_fixed_interval": {"observation_mode": "rich", "decision_interval_s": 30.0},
}


@contextlib.contextmanager
def strict_warnings() -> Iterator[list[warnings.WarningMessage]]:
    """Every warning raised inside is a test failure unless it is a tolerated advisory."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield caught
    bad = sorted(
        {
            f"{w.category.__name__}: {w.message}"
            for w in caught
            if not any(p.search(str(w.message)) for p in TOLERATED_WARNINGS)
        }
    )
    if bad:
        pytest.fail("unexpected warnings:\n" + "\n".join(bad))


def seed_spaces(env: Any, seed: int = 0) -> Any:
    """Seed every agent's action and observation space (the checkers sample from them), so a
    checker's random actions are reproducible. Returns `env`."""
    for i, agent in enumerate(env.possible_agents):
        env.action_space(agent).seed(seed + i)
        env.observation_space(agent).seed(seed + i)
    return env


def random_policy(obs: dict[str, Any], infos: dict[str, Any], rng: np.random.Generator) -> dict:
    """A uniformly random circuit for every robot that must decide; nothing for the others. (The
    mask is in the observation, or in the info with `observation_format="box"`.)"""
    return {
        a: int(
            rng.choice(
                np.flatnonzero((obs[a] if isinstance(obs[a], dict) else infos[a])["action_mask"])
            )
        )
        for a in obs
        if infos[a]["action_required"]
    }


def constant_policy(circuit: int) -> Policy:
    """Every deciding robot chooses `circuit`."""

    def policy(obs: dict[str, Any], infos: dict[str, Any], rng: np.random.Generator) -> dict:
        return {a: circuit for a in obs if infos[a]["action_required"]}

    return policy


@dataclass
class StepRecord:
    """Everything observable about one env step (or about the reset, with `actions` None)."""

    actions: dict[str, Any] | None
    obs: dict[str, Any]
    rewards: dict[str, float]
    terminations: dict[str, bool]
    truncations: dict[str, bool]
    infos: dict[str, Any]
    state: np.ndarray
    positions: np.ndarray
    time_s: float
    duration_s: float = 0.0


@dataclass
class Run:
    records: list[StepRecord] = field(default_factory=list)

    @property
    def reset(self) -> StepRecord:
        return self.records[0]

    @property
    def steps(self) -> list[StepRecord]:
        return self.records[1:]

    @property
    def last(self) -> StepRecord:
        return self.records[-1]


def _record(env: Any, actions: Any, out: tuple[Any, ...], duration: float) -> StepRecord:
    if len(out) == 2:
        obs, infos = out
        rewards, terms, truncs = {}, {}, {}
    else:
        obs, rewards, terms, truncs, infos = out
    return StepRecord(
        actions,
        obs,
        rewards,
        terms,
        truncs,
        infos,
        env.state(),
        env.sim.positions(),
        env.sim.time_s,
        duration,
    )


def run_env(
    env: tavc_env.TavcArenaEnv,
    steps: int,
    policy: Policy = random_policy,
    seed: int | None = 0,
    policy_seed: int = 0,
) -> Run:
    """Reset `env` with `seed` and step it `steps` times (or until every agent is done) with
    `policy` (its rng seeded with `policy_seed`); records the reset and every step."""
    rng = np.random.default_rng(policy_seed)
    out: tuple[Any, ...] = env.reset(seed=seed)
    run = Run([_record(env, None, out, 0.0)])
    for _ in range(steps):
        if not env.agents:
            break
        actions = policy(out[0], out[-1], rng)
        before = env.sim.time_s
        out = env.step(actions)
        run.records.append(_record(env, actions, out, env.sim.time_s - before))
    return run


def assert_same_step(a: StepRecord, b: StepRecord, where: str = "") -> None:
    """Exact equality of everything two envs returned, of their global state and positions."""
    for name in ("obs", "rewards", "terminations", "truncations", "infos"):
        assert data_equivalence(getattr(a, name), getattr(b, name), exact=True), (
            f"{where}: {name} differ:\n{getattr(a, name)}\n{getattr(b, name)}"
        )
    assert np.array_equal(a.state, b.state), f"{where}: state() differs"
    assert np.array_equal(a.positions, b.positions), f"{where}: positions differ"
    assert a.time_s == b.time_s, f"{where}: sim time differs ({a.time_s} vs {b.time_s})"


@dataclass
class Lockstep:
    completions: int  # task completions seen
    obs: dict[str, Any]  # env_a's last observations and infos
    infos: dict[str, Any]


def lockstep(
    env_a: tavc_env.TavcArenaEnv,
    env_b: tavc_env.TavcArenaEnv,
    steps: int,
    start: tuple[dict[str, Any], dict[str, Any]],
    policy: Policy = random_policy,
    policy_seed: int = 0,
    extra_b: Callable[[dict[str, Any], dict[str, Any]], dict[str, Any]] | None = None,
) -> Lockstep:
    """Step two envs (both at the point where `start` = (obs, infos) was returned) with the same
    actions (env_b's optionally extended by `extra_b(obs, infos)`), asserting identical results at
    every step."""
    rng = np.random.default_rng(policy_seed)
    obs, infos = start
    completions = 0
    for k in range(steps):
        if not env_a.agents:
            assert not env_b.agents
            break
        actions = policy(obs, infos, rng)
        actions_b = dict(actions)
        if extra_b is not None:
            actions_b.update(extra_b(obs, infos))
        out_a = env_a.step(actions)
        out_b = env_b.step(actions_b)
        assert_same_step(
            _record(env_a, actions, out_a, 0.0), _record(env_b, actions, out_b, 0.0), f"step {k}"
        )
        obs, infos = out_a[0], out_a[-1]
        completions += sum(completed_task_s(i) is not None for i in infos.values())
    return Lockstep(completions, obs, infos)


def pairwise_min_distance(positions: np.ndarray, present: np.ndarray | None = None) -> float:
    """Smallest centre distance between two (present) robots."""
    p = positions if present is None else positions[present]
    if len(p) < 2:
        return float("inf")
    d = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
    return float(d[np.triu_indices(len(p), 1)].min())


# -- the crowded run ---------------------------------------------------------------------------

CROWD_DURATION_S = 1800.0


@dataclass
class CrowdTrace:
    """Tick-by-tick record of a crowded run (T ticks, n robots, S stations)."""

    config: tavc_env.ArenaConfig
    speeds: np.ndarray  # (n,) nominal top speeds
    time_s: np.ndarray  # (T,)
    pos: np.ndarray  # (T, n, 2)
    mode: np.ndarray  # (T, n) tavc_env.engine.tasks.Mode
    station: np.ndarray  # (T, n) station index or -1
    target: np.ndarray  # (T, n, 2)
    present: np.ndarray  # (T, n) physically on the floor
    occupant: np.ndarray  # (T, S) robot owning the station's dock, or -1
    lines: list[tuple[tuple[int, ...], ...]]  # per tick, per station: robots waiting, head first
    slots: list[np.ndarray]  # per station: its waiting slots
    completed: np.ndarray  # (n,) tasks completed in the run
    rewards: np.ndarray  # (n,) summed rewards


def record_crowd_run(seed: int = 0) -> CrowdTrace:
    """All six `dahl2004` robots serve circuit 0 for 30 simulated minutes (three start at circuit 1's
    sink and cross over), one env step per physics tick (fixed-interval mode with
    `decision_interval_s = dt`), recorded every tick."""
    config = tavc_env.preset("dahl2004")
    env = tavc_env.parallel_env(decision_interval_s=config.dt, max_sim_time_s=CROWD_DURATION_S)
    obs, infos = env.reset(seed=seed)
    sim = env.sim
    tasks = sim.tasks
    rec: dict[str, list[Any]] = {k: [] for k in ("t", "pos", "mode", "st", "tgt", "pres", "occ")}
    lines: list[tuple[tuple[int, ...], ...]] = []
    total = np.zeros(config.n_robots)
    while env.agents:
        obs, rewards, _, _, infos = env.step({a: 0 for a in obs if infos[a]["action_required"]})
        total += [rewards[a] for a in env.possible_agents]
        rec["t"].append(sim.time_s)
        rec["pos"].append(sim.positions())
        rec["mode"].append(tasks.mode.copy())
        rec["st"].append(tasks.station.copy())
        rec["tgt"].append(tasks.target.copy())
        rec["pres"].append(sim.world.in_space.copy())
        rec["occ"].append([s.occupant for s in tasks.stations])
        lines.append(tuple(tuple(s.line) for s in tasks.stations))
    return CrowdTrace(
        config=config,
        speeds=sim.speeds.copy(),
        time_s=np.array(rec["t"]),
        pos=np.array(rec["pos"]),
        mode=np.array(rec["mode"]),
        station=np.array(rec["st"]),
        target=np.array(rec["tgt"]),
        present=np.array(rec["pres"]),
        occupant=np.array(rec["occ"]),
        lines=lines,
        slots=[s.slots.copy() for s in tasks.stations],
        completed=tasks.completed.copy(),
        rewards=total,
    )


def figure_problems(figure: Any) -> list[str]:
    """What keeps a matplotlib figure from standing alone: axes without labels, bar charts whose
    value axis does not start at zero (so heights do not compare as ratios), several labelled
    series without a legend."""
    problems = []
    for k, ax in enumerate(figure.axes):
        if not ax.get_visible() or not ax.has_data():
            continue
        name = ax.get_title() or f"axes {k}"
        colorbar = getattr(ax, "_colorbar", None)
        if colorbar is not None:  # a colour scale says what its colours measure
            if not (ax.get_ylabel() or ax.get_xlabel()):
                problems.append(f"{name}: a colour bar without a label")
            continue
        beside = ax.get_shared_y_axes().get_siblings(ax)  # (panels side by side on one y axis)
        if not any(a.get_ylabel() or a.get_yticklabels() for a in beside):
            problems.append(f"{name}: no y label")
        shared = ax.get_shared_x_axes().get_siblings(ax)  # (panels stacked on one time axis)
        if not any(
            a.get_xlabel() or any(t.get_text() for t in a.get_xticklabels()) for a in shared
        ):
            problems.append(f"{name}: no x label")
        bars = [c for c in ax.containers if type(c).__name__ == "BarContainer"]
        if bars:
            horizontal = getattr(bars[0], "orientation", "vertical") == "horizontal"
            low = (ax.get_xlim() if horizontal else ax.get_ylim())[0]
            if low > 0:
                problems.append(f"{name}: bars start at {low:g}, not at zero")
        labelled = [
            a
            for a in [*ax.get_lines(), *ax.collections, *ax.containers]
            if not str(a.get_label()).startswith("_")
        ]
        if len(labelled) > 1 and ax.get_legend() is None and figure.legends == []:
            problems.append(f"{name}: {len(labelled)} labelled series and no legend")
    return problems


def png_size(path: Any) -> tuple[int, int]:
    """The width and height in pixels of the PNG at `path` (from its header)."""
    head = open(path, "rb").read(24)  # noqa: SIM115
    assert head[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def check_figure_only(
    run: Callable[[Any], Any], settings: Callable[..., Any], committed: Any, figure: str, tmp: Any
) -> tuple[int, int]:
    """A study's `--figure-only` run (`run(settings(out=..., figure_only=True))`) on a copy of its
    `committed` results folder, without the figure: it writes the figure and nothing else (every
    other file byte for byte as it was), and in a folder without a report it refuses, naming the
    missing file, before drawing anything. Returns the figure's size in pixels."""
    import shutil
    from pathlib import Path

    out = Path(tmp) / "run"
    shutil.copytree(committed, out, ignore=shutil.ignore_patterns(figure))
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    outcome = run(settings(out=out, figure_only=True))
    assert outcome.written == [out / figure]
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert set(after) == {*before, figure}
    assert all(after[name] == data for name, data in before.items())
    empty = Path(tmp) / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match=r"^figure_only: there is no report '.*empty/"):
        run(settings(out=empty, figure_only=True))
    assert list(empty.iterdir()) == []
    return png_size(out / figure)


BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
NOT_STUDIES = ("arena_analysis", "arena_runs", "profile_env", "regime_cell")
"""benchmarks/ modules that are not study programs: the modules the studies share, and two
scripts of their own (a run to profile, one regime-map cell rerun)."""


def study_programs() -> dict[str, ModuleType]:
    """Every study program of benchmarks/ by name (a module with `Settings` and `run`), imported
    as the tests import them (benchmarks/ is on pytest's pythonpath)."""
    found = {}
    for path in sorted(BENCHMARKS.glob("*.py")):
        if path.stem not in NOT_STUDIES:
            module = importlib.import_module(path.stem)
            assert hasattr(module, "Settings") and hasattr(module, "run"), path
            found[path.stem] = module
    return found
