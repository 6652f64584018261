"""Observation modes and formats, numeric infos (v1) and the v0 env kept for saved work."""

from __future__ import annotations

import math

import numpy as np
import pettingzoo
import pytest

import tavc_env
import tavc_env.v0
from tavc_env import PHASES, completed_task_s
from tavc_env.observations import TIME_SCALE_S, feature_names
from tests.helpers import run_env
from tests.tavc_env.test_twin import tables_for


def _steps(**kwargs: object) -> list[tuple[dict, dict, dict]]:
    env = tavc_env.parallel_env(**kwargs)  # type: ignore[arg-type]
    run = run_env(env, 40, seed=5, policy_seed=6)
    return [(rec.obs, rec.rewards, rec.infos) for rec in run.steps]


@pytest.mark.parametrize("mode", tavc_env.OBSERVATION_MODES)
@pytest.mark.parametrize("fmt", tavc_env.OBSERVATION_FORMATS)
def test_observation_vectors_have_named_entries_and_stay_in_their_space(
    mode: str, fmt: str
) -> None:
    env = tavc_env.parallel_env(observation_mode=mode, observation_format=fmt)
    n, m = env.config.n_robots, env.config.n_circuits
    space = env.observation_space("robot_0")
    vector_space = space["observation"] if fmt == "dict" else space
    names = feature_names(env.config, mode)
    assert vector_space.shape == (len(names),) and len(set(names)) == len(names)
    # rich: paper_id + pose (2) + heading (2) + velocity (2) + phase (4) + time (1) + 3 per circuit
    assert len(names) == {"paper": m, "paper_id": m + n, "rich": 4 * m + n + 11}[mode]
    run = run_env(env, 30, seed=2, policy_seed=3)
    for rec in run.steps:
        for a in rec.obs:
            assert space.contains(rec.obs[a])
            vec = rec.obs[a]["observation"] if fmt == "dict" else rec.obs[a]
            mask = rec.obs[a]["action_mask"] if fmt == "dict" else rec.infos[a]["action_mask"]
            i = env.possible_agents.index(a)
            assert vec[names.index(f"last_circuit_{rec.infos[a]['circuit']}")] == 1.0
            assert vec[:m].sum() == 1.0
            if mode != "paper":
                assert vec[m + i] == 1.0 and vec[m : m + n].sum() == 1.0
            want = np.ones(m) if rec.infos[a]["action_required"] else vec[:m]
            assert np.array_equal(mask, want)


def test_the_mode_changes_what_robots_see_not_what_happens() -> None:
    """Same seed, same actions: rewards and infos (but the mask) are equal in every mode."""
    reference = _steps()
    for kwargs in (
        {"observation_mode": "rich", "observation_format": "box"},
        {"observation_mode": "paper_id"},
    ):
        for (_, r0, i0), (_, r1, i1) in zip(reference, _steps(**kwargs), strict=True):
            assert r0 == r1
            for a in i0:
                assert i0[a] == {k: v for k, v in i1[a].items() if k != "action_mask"}


def test_rich_observations_show_speed_crowding_task_times_and_values() -> None:
    env = tavc_env.parallel_env(observation_mode="rich")
    cfg = env.config
    names = feature_names(cfg, "rich")
    col = {name: k for k, name in enumerate(names)}
    run = run_env(env, 60, seed=4, policy_seed=1)
    speeds: dict[str, list[float]] = {"fast": [], "slow": []}
    last: dict[str, float] = {}
    for rec in run.steps:
        serving = np.zeros(cfg.n_circuits)
        for info in rec.infos.values():
            if PHASES[info["phase"]] in ("to_source", "to_sink"):
                serving[info["circuit"]] += 1
        for a, vec in rec.obs.items():
            v = vec["observation"]
            i = env.possible_agents.index(a)
            speed = math.hypot(v[col["vx"]], v[col["vy"]])
            cls = cfg.robots[i].speed_class
            speeds[cls].append(speed)
            info = rec.infos[a]
            assert v[col[f"phase_{PHASES[info['phase']]}"]] == 1.0
            assert v[col["time_since_decision"]] == pytest.approx(
                min(info["elapsed_s"] / TIME_SCALE_S, 1.0), abs=1e-6
            )
            for c in range(cfg.n_circuits):
                assert v[col[f"robots_on_circuit_{c}"]] == pytest.approx(serving[c] / cfg.n_robots)
                w = [circuit.value for circuit in cfg.circuits]
                assert v[col[f"value_circuit_{c}"]] == pytest.approx(w[c] / max(w))
            t = completed_task_s(info)
            if t is not None:
                last[f"{a}/{info['circuit']}"] = t
            for c in range(cfg.n_circuits):
                want = last.get(f"{a}/{c}", 0.0) / TIME_SCALE_S
                got = v[col[f"last_task_time_circuit_{c}"]]
                assert got == pytest.approx(min(want, 1.0), abs=1e-6)
    # velocity is scaled by the fastest top speed: moving fast robots read about 1, slow ones 2/3
    # (0.20 / 0.30 m/s); contacts may push a robot faster for a moment
    cruising = {cls: np.median([x for x in v if x > 0.3]) for cls, v in speeds.items()}
    assert cruising["fast"] == pytest.approx(1.0, abs=0.05)
    assert cruising["slow"] == pytest.approx(2 / 3, abs=0.05)
    assert last, "some task completed"


def test_infos_hold_only_numbers_and_booleans() -> None:
    """What TorchRL and BenchMARL need: every info value becomes a tensor (no str, no None)."""
    for kwargs in ({}, {"observation_format": "box"}):
        for _, _, infos in _steps(**kwargs):
            for info in infos.values():
                for key, value in info.items():
                    assert isinstance(value, (bool, int, float, np.ndarray)), key
                    assert np.isfinite(np.asarray(value, dtype=float)).all(), key


def test_v0_keeps_names_and_none_on_the_same_trajectory() -> None:
    v1 = tavc_env.parallel_env()
    v0 = tavc_env.v0.parallel_env()
    assert v0.metadata["name"] == "tavc_arena_v0" and v1.metadata["name"] == "tavc_arena_v1"
    run1, run0 = run_env(v1, 40, seed=9, policy_seed=2), run_env(v0, 40, seed=9, policy_seed=2)
    completions = 0
    for a_rec, b_rec in zip(run1.steps, run0.steps, strict=True):
        assert a_rec.rewards == b_rec.rewards
        assert np.array_equal(a_rec.state, b_rec.state)
        for a, new in a_rec.infos.items():
            old = b_rec.infos[a]
            assert old["phase"] == PHASES[new["phase"]]
            assert old["task_time_s"] == completed_task_s(new) == completed_task_s(old)
            assert "task_completed" not in old
            completions += old["task_time_s"] is not None
    assert completions > 10


def test_both_versions_are_registered() -> None:
    if not hasattr(pettingzoo, "make"):
        pytest.skip("this PettingZoo has no registry")
    v1 = pettingzoo.make("parallel", tavc_env.REGISTRY_ID, observation_mode="rich")
    v0 = pettingzoo.make("parallel", tavc_env.REGISTRY_ID_V0)
    assert isinstance(v1, tavc_env.TavcArenaEnv) and v1.observation_mode == "rich"
    assert isinstance(v0, tavc_env.v0.TavcArenaEnvV0)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        (
            {"observation_mode": "full"},
            r"observation_mode = 'full' is invalid; allowed: .*paper_id",
        ),
        (
            {"observation_format": "flat"},
            r"observation_format = 'flat' is invalid; allowed: .*'box'",
        ),
    ],
)
def test_bad_observation_arguments_are_named(kwargs: dict[str, str], pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        tavc_env.parallel_env(**kwargs)  # type: ignore[arg-type]


def test_v0_and_the_twin_refuse_what_they_cannot_show() -> None:
    with pytest.raises(ValueError, match=r"observation_mode = 'rich' is invalid.*v0 has no other"):
        tavc_env.v0.parallel_env(observation_mode="rich")
    tables = tables_for(tavc_env.preset("dahl2004"))
    with pytest.raises(ValueError, match=r"observation_mode = 'rich' is invalid.*no positions"):
        tavc_env.twin_parallel_env(tables=tables, observation_mode="rich")
    twin = tavc_env.twin_parallel_env(tables=tables, observation_mode="paper_id")
    obs, _ = twin.reset(seed=1)
    assert twin.observation_space("robot_2").contains(obs["robot_2"])
