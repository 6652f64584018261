"""The trial runner and the sweep runner (tavc_agents.experiments.runner, tavc_agents.experiments.sweep): determinism, the JSON round
trip, the recorded timeline against the deliveries, Q snapshots and learner statistics, what a
policy is shown (a spy policy records every call), bad input, and the sweep's resume and parallel
equality."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_agents.allocators.baselines import RandomAllocator
from tavc_agents.experiments.folders import LOCK_FILE
from tavc_agents.experiments.runner import TrialResult, env_arguments, run_trial
from tavc_agents.experiments.sweep import TrialSpec, result_path, run_spec, run_sweep
from tavc_agents.learners.tavc import TavcLearner, softmax_tavc

AGENTS = [f"robot_{i}" for i in range(6)]
HOUR = {"convergence_s": 2400.0, "measured_s": 1200.0}  # one simulated hour, about 1 s of wall time
MS = 1000.0  # the default reward time unit: w / t with t in ms


def comparable(result: TrialResult) -> dict[str, Any]:
    """Everything a trial recorded except its wall-clock time and the sweep's provenance record."""
    d = result.to_dict()
    d.pop("wall_s")
    d.pop("spec")
    return d


@pytest.fixture(scope="module")
def softmax_hour() -> tuple[TrialResult, dict[str, TavcLearner]]:
    """One simulated hour of softmax TAVC on dahl2004 (seed 0), with the learners kept."""
    learners = {a: softmax_tavc() for a in AGENTS}
    result = run_trial(learners, seed=0, arena="dahl2004", label="softmax", **HOUR)
    return result, learners


# -- determinism and serialisation -------------------------------------------------------------


def test_same_seed_same_result_different_seed_different(softmax_hour) -> None:
    first, _ = softmax_hour
    again = run_trial(
        lambda agent: softmax_tavc(), seed=0, arena="dahl2004", label="softmax", **HOUR
    )
    assert comparable(again) == comparable(first)
    other = run_trial(
        lambda agent: softmax_tavc(), seed=1, arena="dahl2004", label="softmax", **HOUR
    )
    assert other.changes != first.changes
    assert other.delivery_time_s != first.delivery_time_s
    assert other.q_snapshots[-1] != first.q_snapshots[-1]


def test_result_round_trips_through_json(softmax_hour, tmp_path: Path) -> None:
    result, _ = softmax_hour
    path = tmp_path / "trial.json"
    result.save(path)
    assert not path.with_suffix(".json.tmp").exists()
    raw = json.loads(path.read_text())  # plain JSON (no NaN, no Python objects)
    assert raw["seed"] == 0 and raw["env_kwargs"] == {"preset": "dahl2004"}
    loaded = TrialResult.load(path)
    assert loaded.to_dict() == result.to_dict()
    assert all(isinstance(c, tuple) for c in loaded.changes)
    assert loaded.measured_window == (2400.0, 3600.0)


def test_result_describes_the_trial(softmax_hour) -> None:
    result, _ = softmax_hour
    assert result.agents == AGENTS
    assert result.speed_classes == ["fast"] * 3 + ["slow"] * 3
    assert result.speeds == [0.3] * 3 + [0.2] * 3
    assert result.values == [2200.0, 2000.0]
    assert result.end_s == pytest.approx(3600.0)
    assert result.label == "softmax"
    assert result.steps > 0 and result.capped_steps == 0
    assert len(result.initial_circuits) == 6
    assert set(result.initial_circuits) <= {0, 1}


# -- timeline and deliveries -------------------------------------------------------------------


def test_changes_are_time_ordered_and_real(softmax_hour) -> None:
    result, _ = softmax_hour
    assert len(result.changes) > 20
    times = [t for t, _, _ in result.changes]
    assert times == sorted(times)
    assert times[0] >= 0.0 and times[-1] < result.end_s
    current = list(result.initial_circuits)
    for _, robot, circuit in result.changes:
        assert circuit in (0, 1) and circuit != current[robot]  # only actual changes are recorded
        current[robot] = circuit


def test_deliveries_are_consistent_with_the_timeline(softmax_hour) -> None:
    result, _ = softmax_hour
    n = len(result.delivery_time_s)
    assert n > 100
    assert n == len(result.delivery_robot) == len(result.delivery_circuit)
    assert n == len(result.delivery_task_time_s)
    assert result.delivery_time_s == sorted(result.delivery_time_s)
    last_decision = [0.0] * 6
    for t, robot, circuit, task in zip(
        result.delivery_time_s,
        result.delivery_robot,
        result.delivery_circuit,
        result.delivery_task_time_s,
        strict=True,
    ):
        # The robot's current circuit just before t (its next choice is made at t itself).
        current = result.initial_circuits[robot]
        for tc, r, c in result.changes:
            if tc >= t:
                break
            if r == robot:
                current = c
        assert circuit == current, f"delivery at {t} by robot {robot}"
        # the task began at the robot's previous decision (its previous delivery, or t = 0)
        assert task > 0
        assert t - task == pytest.approx(last_decision[robot], abs=1e-6)
        last_decision[robot] = t
    # every change after t = 0 happens at a decision, i.e. right at a delivery of that robot
    deliveries = set(zip(result.delivery_time_s, result.delivery_robot))
    for tc, r, _ in result.changes:
        assert tc == 0.0 or (tc, r) in deliveries


# -- snapshots and learner statistics ----------------------------------------------------------


def test_q_snapshots_hourly_and_final(softmax_hour) -> None:
    result, learners = softmax_hour
    assert [s["time_s"] for s in result.q_snapshots] == [0.0, 3600.0]
    first, last = result.q_snapshots
    assert set(first["q"]) == set(AGENTS)
    assert first["q"]["robot_0"] == [[0.0, 0.0], [0.0, 0.0]]  # scaled init before any reward
    for agent, learner in learners.items():
        assert last["q"][agent] == learner.q_table.tolist()
        assert np.asarray(last["q"][agent]).shape == (2, 2)


def test_q_snapshots_follow_the_period() -> None:
    result = run_trial(
        lambda agent: softmax_tavc(),
        seed=3,
        arena="dahl2004",
        convergence_s=1200.0,
        measured_s=600.0,
        snapshot_every_s=600.0,
    )
    times = [s["time_s"] for s in result.q_snapshots]
    assert len(times) == 4  # 0, 600, 1200 and the final state at 1800
    assert times[0] == 0.0 and times[-1] == pytest.approx(1800.0)
    for k, t in enumerate(times[:-1]):
        # taken at the first step boundary at or after k periods
        assert 600.0 * k <= t < 600.0 * k + 120.0
    assert times == sorted(times)


def test_learner_stats_match_the_learners(softmax_hour) -> None:
    result, learners = softmax_hour
    assert set(result.learner_stats) == set(AGENTS)
    for i, (agent, learner) in enumerate(learners.items()):
        stats = result.learner_stats[agent]
        assert stats["updates"] == learner.updates.tolist()
        assert stats["never_updated"] == int((learner.updates == 0).sum())
        assert stats["choices"] == learner.choices
        assert stats["non_greedy_choices"] == learner.non_greedy_choices
        # one update per completed task, one choice per decision (the first at t = 0)
        delivered = sum(
            r == i and t < result.end_s
            for t, r in zip(result.delivery_time_s, result.delivery_robot)
        )
        assert np.sum(stats["updates"]) == delivered
        assert stats["choices"] == delivered + 1


def test_no_learner_stats_or_snapshots_for_random() -> None:
    result = run_trial(
        lambda agent: RandomAllocator(), seed=0, arena="dahl2004", convergence_s=0, measured_s=600
    )
    assert result.learner_stats == {}
    assert result.q_snapshots == []
    assert len(result.delivery_time_s) > 10


# -- what a policy sees ------------------------------------------------------------------------


class SpyPolicy:
    """Records every call (copies of the arrays) and acts randomly."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, ...]] = []
        self._inner = RandomAllocator()

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        self.calls.append(("reset", rng, n_actions))
        self._inner.reset(rng, n_actions)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        action = self._inner.act(observation, action_mask)
        self.calls.append(("act", observation.copy(), action_mask.copy(), action))
        return action

    def update(self, observation, action, reward, next_observation, info) -> None:
        self.calls.append(
            ("update", observation.copy(), action, reward, next_observation.copy(), dict(info))
        )


def assert_onehot(x: np.ndarray) -> None:
    assert isinstance(x, np.ndarray)
    assert x.dtype == np.float32 and x.shape == (2,)
    assert sorted(x.tolist()) == [0.0, 1.0]


@pytest.fixture(scope="module")
def spied() -> tuple[TrialResult, dict[str, SpyPolicy]]:
    spies = {a: SpyPolicy() for a in AGENTS}
    result = run_trial(spies, seed=5, arena="dahl2004", **HOUR)
    return result, spies


def test_spy_sees_only_env_observations(spied) -> None:
    _, spies = spied
    rngs = []
    for spy in spies.values():
        kind, rng, n = spy.calls[0]
        assert kind == "reset" and n == 2 and isinstance(rng, np.random.Generator)
        rngs.append(rng)
        assert [c[0] for c in spy.calls].count("reset") == 1
        for call in spy.calls[1:]:
            if call[0] == "act":
                _, obs, mask, _ = call
                assert_onehot(obs)
                assert mask.dtype == np.int8 and mask.shape == (2,)
                assert mask.tolist() == [1, 1]  # a deciding robot may choose either circuit
            else:
                _, obs, _, _, next_obs, _ = call
                assert_onehot(obs)
                assert_onehot(next_obs)
    # every policy has its own random stream
    assert len({id(r) for r in rngs}) == 6
    assert len({r.random() for r in rngs}) == 6


def test_spy_calls_alternate_act_update(spied) -> None:
    _, spies = spied
    for spy in spies.values():
        kinds = [c[0] for c in spy.calls[1:]]
        assert kinds[0] == "act"
        # act, then (update, act) for every completed task; every update precedes the next act
        assert kinds == ["act"] + ["update", "act"] * ((len(kinds) - 1) // 2) + (
            ["update"] if len(kinds) % 2 == 0 else []
        )
        assert kinds[-1] == "act"


def test_spy_updates_once_per_delivery_with_the_envs_reward(spied) -> None:
    result, spies = spied
    values = result.values
    for i, (agent, spy) in enumerate(spies.items()):
        acts = [c for c in spy.calls if c[0] == "act"]
        updates = [c for c in spy.calls if c[0] == "update"]
        deliveries = [
            (t, c, task)
            for t, r, c, task in zip(
                result.delivery_time_s,
                result.delivery_robot,
                result.delivery_circuit,
                result.delivery_task_time_s,
            )
            if r == i
            and t < result.end_s  # a delivery at the very end is never followed by a decision
        ]
        assert len(deliveries) > 5, agent
        assert len(updates) == len(deliveries), agent
        for k, ((_, obs, action, reward, next_obs, info), (t, circuit, task)) in enumerate(
            zip(updates, deliveries, strict=True)
        ):
            prev_act = acts[k]
            # the update is about the previous decision: same observation and action
            assert np.array_equal(obs, prev_act[1]) and action == prev_act[3]
            assert action == circuit
            assert next_obs.tolist() == [float(c == action) for c in range(2)]
            assert info["task_time_s"] == task
            assert info["sim_time_s"] == t
            assert info["circuit"] == circuit
            assert reward == pytest.approx(values[action] / (task * MS), rel=1e-12)
            assert 0.01 < reward < 0.2  # the paper's scale (w / t_ms)


# -- bad input ---------------------------------------------------------------------------------


def test_missing_policies_raise_naming_the_agents() -> None:
    partial = {a: RandomAllocator() for a in AGENTS[:3]}
    with pytest.raises(
        ValueError, match=r"policies missing for \['robot_3', 'robot_4', 'robot_5'\]"
    ):
        run_trial(partial, seed=0, arena="dahl2004", convergence_s=0, measured_s=60)


@pytest.mark.parametrize(
    ("field", "kwargs"),
    [
        ("convergence_s", {"convergence_s": -1.0, "measured_s": 60.0}),
        ("convergence_s", {"convergence_s": math.nan, "measured_s": 60.0}),
        ("convergence_s", {"convergence_s": "60", "measured_s": 60.0}),
        ("measured_s", {"convergence_s": 60.0, "measured_s": -0.5}),
        ("measured_s", {"convergence_s": 60.0, "measured_s": math.nan}),
        ("measured_s", {"convergence_s": 60.0, "measured_s": None}),
        ("convergence_s \\+ measured_s", {"convergence_s": 0.0, "measured_s": 0.0}),
    ],
)
def test_bad_periods_raise(field: str, kwargs: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match=field):
        run_trial(lambda agent: RandomAllocator(), seed=0, arena="dahl2004", **kwargs)


# -- the trial's arena and options: explicit arguments ----------------------------------------


def test_a_misspelt_argument_is_an_unknown_run_trial_argument() -> None:
    """`convergence_h` used to be reported as an unknown arena key."""
    with pytest.raises(TypeError, match=r"run_trial\(\) got an unexpected keyword .*convergence_h"):
        run_trial(lambda agent: RandomAllocator(), seed=0, convergence_h=1.0)  # type: ignore[call-arg]


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        (
            {"arena": {"decision_interval_s": 5.0}},
            r"^arena overrides = \['decision_interval_s'\] is invalid",
        ),
        (
            {"arena": {"sourse_service_s": 5.0}},
            r"^arena overrides = \['sourse_service_s'\] is invalid",
        ),
        ({"options": tavc_env.EnvOptions(max_cycles=5)}, r"^options = \['max_cycles'\] is invalid"),
        ({"options": {"step_cap_s": 60.0}}, r"^options = .* allowed: a tavc_env\.EnvOptions"),
        (
            {"arena": {"preset": "dahl2004", "config": tavc_env.preset("dahl2004")}},
            r"^arena = \{'preset': 'dahl2004', 'config': .*\} is invalid; allowed: one of a "
            r"scenario, a preset or a config",
        ),
        (
            {"arena": {"scenario": "bad_start", "preset": "dahl2004"}},
            r"^arena = \{'scenario': 'bad_start', 'preset': 'dahl2004'\} is invalid",
        ),
        (
            {"arena": {"scenario": "bad_start", "dt": 0.05}},
            r"^scenario 'bad_start' with arena overrides = \['dt'\] is invalid; allowed: a "
            r"scenario alone",
        ),
        ({"arena": "bad_stat"}, r"^arena = 'bad_stat' is invalid; allowed: a preset \(dahl2004, "),
        (
            {"arena": "bad_start", "env_factory": lambda **kwargs: None},
            r"^env factory = .* is invalid; allowed: None for scenario 'bad_start'",
        ),
    ],
)
def test_the_arena_and_options_are_checked_before_the_trial(
    kwargs: dict[str, Any], pattern: str
) -> None:
    with pytest.raises(ValueError, match=pattern):
        run_trial(lambda agent: RandomAllocator(), seed=0, progress=_guard, **HOUR, **kwargs)


@pytest.mark.parametrize("spec", ["bad_start", "tavc/bad_start-v0", {"scenario": "bad_start"}])
def test_a_trial_takes_a_scenario_through_the_one_door(spec: Any) -> None:
    seen: list[Any] = []
    result = run_trial(
        lambda agent: RandomAllocator(),
        seed=0,
        convergence_s=0.0,
        measured_s=300.0,
        arena=spec,
        on_step=seen.append,
    )
    assert isinstance(seen[0], tavc_env.ScenarioEnv) and seen[0].scenario.name == "bad_start"
    assert result.initial_circuits == [1, 1, 1, 0, 1, 1]
    assert result.env_kwargs == {"scenario": "bad_start"}
    by_spec = run_spec(
        TrialSpec(
            key="k",
            allocator="random",
            seed=0,
            env_kwargs={"scenario": "bad_start"},
            convergence_s=0.0,
            measured_s=300.0,
        )
    )
    assert by_spec.delivery_time_s == result.delivery_time_s


def test_arena_and_options_reach_the_env_and_the_record() -> None:
    seen: list[Any] = []
    options = tavc_env.EnvOptions(decision_interval_s=30.0, reward_time_unit="s")
    result = run_trial(
        lambda agent: RandomAllocator(),
        seed=0,
        convergence_s=0.0,
        measured_s=120.0,
        arena={"preset": "dahl2004_homogeneous", "source_service_s": 5.0},
        options=options,
        on_step=seen.append,
    )
    env = seen[0]
    assert env.config == tavc_env.make_config("dahl2004_homogeneous", source_service_s=5.0)
    assert env.options == options.replace(max_sim_time_s=120.0, max_cycles=10**9)
    assert result.steps == 4  # fixed 30 s steps
    assert result.env_kwargs == {
        "preset": "dahl2004_homogeneous",
        "source_service_s": 5.0,
        "decision_interval_s": 30.0,
        "reward_time_unit": "s",
    }
    # the same trial from its plain record, as a sweep runs it
    assert env_arguments(result.env_kwargs) == {
        "arena": tavc_env.resolve_arena("dahl2004_homogeneous", source_service_s=5.0),
        "options": options,
    }
    spec = TrialSpec(
        key="k",
        allocator="random",
        seed=0,
        env_kwargs=result.env_kwargs,
        convergence_s=0.0,
        measured_s=120.0,
    )
    again = run_spec(spec)
    assert again.env_kwargs == result.env_kwargs and again.steps == result.steps
    with pytest.raises(ValueError, match=r"unknown configuration key\(s\) \['presett'\]"):
        env_arguments({"presett": "dahl2004"})
    config = tavc_env.preset("dahl2004")
    assert env_arguments({"config": config}) == {"arena": tavc_env.resolve_arena(config)}


class _Runaway(Exception):
    """Raised by the progress guard: the trial ran although it should have been rejected."""


def _guard(sim_time_s: float) -> None:
    if sim_time_s > 120.0:
        raise _Runaway(f"still running at {sim_time_s} s")


@pytest.mark.parametrize("field", ["convergence_s", "measured_s"])
def test_infinite_period_raises(field: str) -> None:
    kwargs = {"convergence_s": 60.0, "measured_s": 60.0, field: math.inf}
    with pytest.raises(ValueError, match=field):
        run_trial(
            lambda agent: RandomAllocator(), seed=0, arena="dahl2004", progress=_guard, **kwargs
        )


@pytest.mark.parametrize("period", [0.0, -600.0, math.nan])
def test_bad_snapshot_period_raises(period: float) -> None:
    with pytest.raises(ValueError, match="snapshot_every_s"):
        run_trial(
            lambda agent: softmax_tavc(),
            seed=0,
            arena="dahl2004",
            convergence_s=0.0,
            measured_s=120.0,
            snapshot_every_s=period,
        )


# -- sweep -------------------------------------------------------------------------------------

TINY = {"convergence_s": 180.0, "measured_s": 180.0}  # 0.1 simulated hours


def tiny_specs() -> list[TrialSpec]:
    env = {"preset": "dahl2004"}
    return [
        TrialSpec(key="softmax_seed0", allocator="softmax_tavc", seed=0, env_kwargs=env, **TINY),
        TrialSpec(key="softmax_seed1", allocator="softmax_tavc", seed=1, env_kwargs=env, **TINY),
        TrialSpec(
            key="epsilon_seed0",
            allocator="epsilon_tavc",
            seed=0,
            env_kwargs=env,
            allocator_kwargs={"epsilon": 0.2},
            **TINY,
        ),
        TrialSpec(key="random_seed0", allocator="random", seed=0, env_kwargs=env, **TINY),
    ]


def run_recording(specs, out, workers):
    done: list[tuple[str, bool]] = []
    results = run_sweep(
        specs, out, workers=workers, on_done=lambda s, r, resumed: done.append((s.key, resumed))
    )
    return results, done


@pytest.fixture(scope="module")
def sweep_once(tmp_path_factory) -> tuple[Path, dict[str, TrialResult], list[tuple[str, bool]]]:
    out = tmp_path_factory.mktemp("sweep1")
    results, done = run_recording(tiny_specs(), out, workers=1)
    return out, results, done


def test_sweep_runs_and_saves_every_trial(sweep_once) -> None:
    out, results, done = sweep_once
    keys = [s.key for s in tiny_specs()]
    assert list(results) == keys
    assert done == [(k, False) for k in keys]
    # each trial's file, and the lock the sweep held on the folder (experiments.folders)
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [LOCK_FILE, *(f"{k}.json" for k in keys)]
    )
    for spec in tiny_specs():
        r = results[spec.key]
        assert r.label == spec.key and r.seed == spec.seed
        assert r.end_s == pytest.approx(360.0)
        assert TrialResult.load(result_path(out, spec.key)).to_dict() == r.to_dict()
    # the spec's allocator was used: learners for TAVC, none for random
    assert results["softmax_seed0"].learner_stats and not results["random_seed0"].learner_stats
    # the same as running the trial directly
    direct = run_trial(
        lambda a: softmax_tavc(), seed=1, arena="dahl2004", label="softmax_seed1", **TINY
    )
    assert comparable(direct) == comparable(results["softmax_seed1"])


def test_sweep_resumes_and_recomputes_only_missing(sweep_once, tmp_path: Path) -> None:
    first_out, first, _ = sweep_once
    out = tmp_path / "sweep"
    out.mkdir()
    for p in first_out.iterdir():
        (out / p.name).write_bytes(p.read_bytes())
    (out / "epsilon_seed0.json").unlink()
    again, done = run_recording(tiny_specs(), out, workers=1)
    assert sorted(done) == sorted(
        [
            ("softmax_seed0", True),
            ("softmax_seed1", True),
            ("epsilon_seed0", False),
            ("random_seed0", True),
        ]
    )
    assert set(again) == set(first)
    for key in first:
        assert comparable(again[key]) == comparable(first[key]), key
    # resumed results are loaded as stored, wall time included
    assert again["softmax_seed0"].to_dict() == first["softmax_seed0"].to_dict()
    assert (out / "epsilon_seed0.json").exists()
    # a third run recomputes nothing
    _, done = run_recording(tiny_specs(), out, workers=1)
    assert all(resumed for _, resumed in done) and len(done) == 4


def test_sweep_parallel_equals_serial(sweep_once, tmp_path: Path) -> None:
    _, serial, _ = sweep_once
    parallel, done = run_recording(tiny_specs(), tmp_path, workers=2)
    assert sorted(done) == sorted((k, False) for k in serial)
    for key in serial:
        assert comparable(parallel[key]) == comparable(serial[key]), key


def test_sweep_duplicate_and_bad_keys_raise(tmp_path: Path) -> None:
    spec = tiny_specs()[0]
    with pytest.raises(ValueError, match=r"duplicate trial keys \['softmax_seed0'\]"):
        run_sweep([spec, tiny_specs()[1], spec], tmp_path / "dup", workers=1)
    assert not (tmp_path / "dup").exists()  # nothing ran, nothing was written
    for bad in ["", "a/b", "../escape", "with space", "tab\tkey"]:
        with pytest.raises(ValueError, match=r"key = .* is invalid"):
            TrialSpec(key=bad, allocator="random", seed=0)
    with pytest.raises(ValueError, match="workers"):
        run_sweep(tiny_specs()[:2], tmp_path / "w", workers=0)


def test_sweep_unknown_allocator_raises(tmp_path: Path) -> None:
    spec = TrialSpec(key="x", allocator="nope", seed=0, env_kwargs={"preset": "dahl2004"}, **TINY)
    with pytest.raises(ValueError, match="allocator 'nope' is unknown"):
        run_sweep([spec], tmp_path, workers=1)
    assert not result_path(tmp_path, "x").exists()
    # a known allocator without its required parameters: named, with what it takes
    spec = TrialSpec(key="y", allocator="greedy", seed=0, env_kwargs={"preset": "dahl2004"}, **TINY)
    with pytest.raises(
        ValueError, match="allocator 'greedy' needs the parameter model; allowed: model"
    ):
        run_sweep([spec], tmp_path, workers=1)
    assert not result_path(tmp_path, "y").exists()


def test_sweep_does_not_resume_a_result_of_a_different_spec(tmp_path: Path) -> None:
    spec = TrialSpec(
        key="trial", allocator="random", seed=0, env_kwargs={"preset": "dahl2004"}, **TINY
    )
    run_sweep([spec], tmp_path, workers=1)
    changed = TrialSpec(
        key="trial",
        allocator="random",
        seed=1,
        env_kwargs={"preset": "dahl2004"},
        convergence_s=60.0,
        measured_s=60.0,
    )
    try:
        results = run_sweep([changed], tmp_path, workers=1)
    except ValueError:
        return  # refusing a mismatching stored result is fine too
    assert results["trial"].seed == 1
    assert results["trial"].end_s == pytest.approx(120.0)
