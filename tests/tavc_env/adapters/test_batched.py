"""`BatchedArenaEnv`: N arenas stepped together, results stacked. Shapes and dtypes; same seed,
same arrays, and in-process and worker modes (fork and spawn) agree bit for bit with the plain env
stepped by hand; same-step autoreset; a worker's exception is raised here with its traceback; close
is idempotent; workers end when their parent dies, even in the constructor; a frozen worker is
named after `timeout_s` and the batch closed; bad arguments (`n_envs` over `MAX_ENVS` included)
are refused."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_env.adapters.batched import (
    MAX_ENVS,
    MAX_WORKERS,
    BatchedArenaEnv,
    WorkerError,
    WorkerTimeoutError,
)
from tavc_env.arena import make_env
from tavc_env.config import Breakdown
from tavc_env.env import TavcArenaEnv

SHORT = {"preset": "dahl2004", "max_sim_time_s": 300.0}  # an episode of about 15-20 steps


def trajectory(batch: BatchedArenaEnv, seed: int, steps: int) -> list[np.ndarray]:
    """Every array the batch returns over `steps` random steps (actions from a fixed seed)."""
    obs, infos = batch.reset(seed=seed)
    out = [obs, *(infos[k] for k in sorted(infos))]
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        step = batch.step(rng.integers(0, batch.n_circuits, (batch.n_envs, batch.n_agents)))
        out += [step.observations, step.rewards, step.terminated, step.truncated]
        out += [v for k, v in sorted(step.infos.items()) if k != "final_info"]
        out += [v for _, v in sorted(step.infos["final_info"].items())]
    return out


def failing_env(**kwargs: Any) -> TavcArenaEnv:
    """An arena whose step raises (a module-level function: spawn sends it by name)."""
    env = tavc_env.parallel_env(**kwargs)

    def broken_step(choices: Any) -> Any:
        raise ZeroDivisionError("a fault planted in the worker")

    env.advance_choices = broken_step  # type: ignore[method-assign]
    return env


FROZEN_SEED = int(np.random.SeedSequence(0).spawn(2)[1].generate_state(1)[0])  # arena 1's


def freezing_env(**kwargs: Any) -> TavcArenaEnv:
    """An arena whose step never returns once it was reset with `FROZEN_SEED` (arena 1 of a
    batch reset with seed 0): a worker frozen in a step."""
    env = tavc_env.parallel_env(**kwargs)
    reset, step = env.reset, env.advance_choices
    seeds: list[Any] = []

    def recording_reset(seed: Any = None, options: Any = None) -> Any:
        seeds.append(seed)
        return reset(seed=seed, options=options)

    def frozen_step(choices: Any) -> Any:
        if seeds and seeds[0] == FROZEN_SEED:
            time.sleep(3600)
        return step(choices)

    env.reset = recording_reset  # type: ignore[method-assign]
    env.advance_choices = frozen_step  # type: ignore[method-assign]
    return env


def test_shapes_dtypes_and_must_decide() -> None:
    with BatchedArenaEnv(3, env_kwargs=SHORT) as batch:
        obs, infos = batch.reset(seed=0)
        assert obs.shape == (3, 6, 2) and obs.dtype == np.float32
        assert infos["action_required"].all()  # every robot decides at reset
        assert infos["action_mask"].shape == (3, 6, 2) and infos["action_mask"].dtype == np.int8
        step = batch.step(np.zeros((3, 6), np.int64))
        assert step.rewards.shape == (3, 6) and step.rewards.dtype == np.float64
        assert step.terminated.shape == step.truncated.shape == (3,)
        assert step.must_decide.shape == (3, 6) and step.must_decide.dtype == np.bool_
        assert step.must_decide.any(axis=1).all()  # event-driven: someone decides in every arena
        busy = ~step.must_decide
        assert (step.action_masks[busy].sum(axis=-1) == 1).all()  # a busy robot: its own circuit
        for key in ("elapsed_s", "sim_time_s", "task_time_s", "circuit", "phase"):
            assert step.infos[key].shape == (3, 6), key
        assert step.infos["final_obs"].shape == (3, 6, 2) and not step.infos["_final_obs"].any()
        assert batch.observation_space.shape == (3, 6, 2)
        assert batch.metadata["autoreset_mode"].value == "SameStep"


def test_the_batch_is_the_plain_env_stepped_by_hand() -> None:
    """Arena i of the batch is `parallel_env` reset with the i-th seed spawned from the seed."""
    with BatchedArenaEnv(2, env_kwargs=SHORT) as batch:
        obs, _ = batch.reset(seed=7)
        seed = int(np.random.SeedSequence(7).spawn(2)[1].generate_state(1)[0])
        env = tavc_env.parallel_env(**SHORT)
        plain_obs, plain_infos = env.reset(seed=seed)
        agents = env.possible_agents
        for _ in range(5):
            assert np.array_equal(obs[1], np.stack([plain_obs[a]["observation"] for a in agents]))
            actions = np.ones((2, 6), np.int64)
            step = batch.step(actions)
            plain_obs, rewards, _, _, plain_infos = env.step(
                {a: 1 for a in agents if plain_infos[a]["action_required"]}
            )
            obs = step.observations
            assert step.rewards[1].tolist() == [rewards[a] for a in agents]
            assert step.infos["sim_time_s"][1, 0] == plain_infos[agents[0]]["sim_time_s"]


@pytest.mark.parametrize("start_method", ["fork", "spawn"])
def test_worker_modes_agree_with_in_process_bit_for_bit(start_method: str) -> None:
    with BatchedArenaEnv(3, env_kwargs=SHORT) as local:
        expected = trajectory(local, seed=3, steps=40)
    with BatchedArenaEnv(3, workers=2, env_kwargs=SHORT, start_method=start_method) as batch:
        found = trajectory(batch, seed=3, steps=40)
    assert len(found) == len(expected)
    assert all(np.array_equal(a, b) and a.dtype == b.dtype for a, b in zip(found, expected))


def test_same_seed_same_arrays_other_seed_others() -> None:
    with BatchedArenaEnv(2, workers=1, env_kwargs=SHORT) as batch:
        first = trajectory(batch, seed=5, steps=20)
        again = trajectory(batch, seed=5, steps=20)
        other = trajectory(batch, seed=6, steps=20)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert not all(np.array_equal(a, b) for a, b in zip(first, other))


def test_same_step_autoreset_returns_the_finished_episode_in_final_info() -> None:
    with BatchedArenaEnv(2, env_kwargs=SHORT) as batch:
        batch.reset(seed=1)
        rng = np.random.default_rng(1)
        for _ in range(200):
            step = batch.step(rng.integers(0, 2, (2, 6)))
            if step.truncated.any():
                break
        else:
            pytest.fail("no episode ended within 200 steps of a 300-s episode")
        ended = step.truncated
        assert np.array_equal(step.infos["_final_obs"], ended)
        final = step.infos["final_info"]
        assert (final["sim_time_s"][ended] >= 300.0 - 1e-6).all()
        assert not final["action_required"][ended].any()  # nobody decides at truncation
        # the returned rows are the new episode's start: everyone decides, time 0
        assert step.must_decide[ended].all() and (step.infos["sim_time_s"][ended] == 0).all()
        assert (final["sim_time_s"][~ended] == 0).all()  # rows of other arenas are zero
        assert not step.terminated.any()  # the task is continuing: truncation only


def test_a_worker_exception_is_raised_here_with_its_traceback() -> None:
    batch = BatchedArenaEnv(2, workers=2, env_kwargs=SHORT, make_env=failing_env)
    batch.reset(seed=0)
    with pytest.raises(WorkerError, match=r"(?s)ZeroDivisionError: a fault planted.*broken_step"):
        batch.step(np.zeros((2, 6), np.int64))
    pids = batch.worker_pids
    with pytest.raises(ValueError, match="closed"):
        batch.step(np.zeros((2, 6), np.int64))
    batch.close()
    assert all(not _alive(pid) for pid in pids)


def test_close_is_idempotent_and_ends_the_workers() -> None:
    batch = BatchedArenaEnv(2, workers=2, env_kwargs=SHORT)
    pids = batch.worker_pids
    assert len(pids) == 2 and all(_alive(pid) for pid in pids)
    batch.close()
    batch.close()
    assert all(not _alive(pid) for pid in pids)
    with pytest.raises(ValueError, match="closed"):
        batch.reset(seed=0)
    local = BatchedArenaEnv(1, env_kwargs=SHORT)
    local.close()
    local.close()


def test_workers_end_when_their_parent_dies() -> None:
    code = (
        "import sys; from tavc_env.adapters.batched import BatchedArenaEnv\n"
        "b = BatchedArenaEnv(2, workers=2, env_kwargs={'max_sim_time_s': 300.0})\n"
        "print(*b.worker_pids, flush=True); sys.stdin.readline()\n"
    )
    with subprocess.Popen(
        [sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    ) as parent:
        assert parent.stdout is not None
        pids = [int(p) for p in parent.stdout.readline().split()]
        assert len(pids) == 2 and all(_alive(pid) for pid in pids)
        os.kill(parent.pid, signal.SIGKILL)  # no clean-up code runs in the parent
    deadline = time.monotonic() + 10
    while any(_alive(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in pids)


def test_a_frozen_worker_is_named_and_the_batch_closed_within_timeout_s() -> None:
    # defect 5 of issue 35: a frozen worker blocked step forever and left its shared memory
    batch = BatchedArenaEnv(2, workers=2, env_kwargs=SHORT, make_env=freezing_env, timeout_s=2)
    pids, block = batch.worker_pids, _block(batch)
    assert os.path.exists(block)
    batch.reset(seed=0)
    started = time.monotonic()
    with pytest.raises(WorkerTimeoutError) as caught:
        batch.step(np.zeros((2, 6), np.int64))
    took = time.monotonic() - started
    message = str(caught.value)
    assert (
        f"worker 1 of 2 (pid {pids[1]}) did not answer step() within timeout_s = 2.0 s" in message
    )
    assert "worker 0" not in message and "\n" not in message and "allowed: " in message
    assert 2.0 <= took < 10.0
    assert not any(_alive(pid) for pid in pids) and not os.path.exists(block)
    with pytest.raises(ValueError, match="closed"):
        batch.step(np.zeros((2, 6), np.int64))
    batch.close()  # closing again does nothing


def test_workers_building_their_arenas_end_when_their_parent_is_killed() -> None:
    # defect 5 of issue 35: workers outlived a parent killed in the constructor by minutes,
    # holding their memory and the shared block
    code = (
        "import multiprocessing, os, time, tavc_env\n"
        "from tavc_env.adapters.batched import BatchedArenaEnv\n"
        "def slow(**kwargs):\n"
        "    if multiprocessing.parent_process() is not None:\n"
        "        print(os.getpid(), flush=True)\n"
        "        time.sleep(600)\n"
        "    return tavc_env.parallel_env(**kwargs)\n"
        "BatchedArenaEnv(2, workers=2, make_env=slow, start_method='fork')\n"
    )
    with subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, text=True
    ) as parent:
        assert parent.stdout is not None
        pids = [int(parent.stdout.readline()) for _ in range(2)]
        blocks = {_mapped_block(pid) for pid in pids}
        block = blocks.pop()
        assert not blocks and os.path.exists(block)
        os.kill(parent.pid, signal.SIGKILL)  # in the constructor; no clean-up code runs
    deadline = time.monotonic() + 10
    while (any(_alive(p) for p in pids) or os.path.exists(block)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in pids)
    assert not os.path.exists(block)  # the resource tracker unlinked it once the workers ended


def test_timeout_s_bounds_the_wait_for_workers_building_their_arenas() -> None:
    started = time.monotonic()
    with pytest.raises(WorkerTimeoutError, match=r"did not build its arenas within timeout_s"):
        BatchedArenaEnv(2, workers=2, make_env=sleepy_builder, timeout_s=1.5)
    assert time.monotonic() - started < 10.0


def sleepy_builder(**kwargs: Any) -> TavcArenaEnv:
    """Builds arenas in this process at once and in a worker after an hour."""
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        time.sleep(3600)
    return tavc_env.parallel_env(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"n_envs": MAX_ENVS + 1}, "n_envs"),  # defect 5 of issue 35: no bound
        ({"n_envs": 10**9}, "n_envs"),
        ({"n_envs": MAX_ENVS, "workers": MAX_WORKERS + 1}, "workers"),
        ({"n_envs": 1, "timeout_s": 0}, "timeout_s"),
        ({"n_envs": 1, "timeout_s": float("nan")}, "timeout_s"),
        ({"n_envs": 1, "timeout_s": "5"}, "timeout_s"),
        ({"n_envs": 0}, "n_envs"),
        ({"n_envs": 2.0}, "n_envs"),
        ({"n_envs": 2, "workers": 3}, "workers"),
        ({"n_envs": 2, "workers": -1}, "workers"),
        ({"n_envs": 1, "env_kwargs": [("preset", "dahl2004")]}, "env_kwargs"),
        ({"n_envs": 1, "make_env": "parallel_env"}, "make_env"),
        ({"n_envs": 1, "make_env": dict}, "make_env"),
        ({"n_envs": 1, "workers": 1, "start_method": "teleport"}, "start_method"),
        ({"n_envs": 1, "env_kwargs": {"speeds": "fast"}}, "speeds"),
    ],
)
def test_bad_arguments_are_refused(kwargs: dict[str, Any], name: str) -> None:
    with pytest.raises(ValueError, match=rf"{name}.* is invalid; allowed: "):
        BatchedArenaEnv(**kwargs)


def test_a_factory_spawn_cannot_send_is_refused() -> None:
    def local_factory(**kwargs: Any) -> TavcArenaEnv:
        return tavc_env.parallel_env(**kwargs)

    with pytest.raises(ValueError, match=r"make_env = .*local_factory.* is invalid with start"):
        BatchedArenaEnv(2, workers=2, make_env=local_factory, start_method="spawn")


def test_bad_actions_and_seeds_are_refused() -> None:
    with BatchedArenaEnv(2, env_kwargs=SHORT) as batch:
        with pytest.raises(ValueError, match="before reset"):
            batch.step(np.zeros((2, 6), np.int64))
        with pytest.raises(ValueError, match=r"seed = -1 is invalid"):
            batch.reset(seed=-1)
        batch.reset(seed=0)
        with pytest.raises(ValueError, match=r"actions = .*shape \(2, 5\).* allowed: an integer"):
            batch.step(np.zeros((2, 5), np.int64))
        with pytest.raises(ValueError, match=r"actions = .*float64"):
            batch.step(np.zeros((2, 6)))
        bad = np.zeros((2, 6), np.int64)
        bad[1, 4] = 2
        with pytest.raises(
            ValueError, match=r"actions\[1, 4\] = 2 is invalid; allowed: .*\[0, 1\]"
        ):
            batch.step(bad)
        step = batch.step(np.zeros((2, 6), np.int64))  # a rejected step changed nothing
        idle = np.where(step.must_decide, 0, 99)  # entries of robots that need not decide: unread
        batch.step(idle)


def _block(batch: BatchedArenaEnv) -> str:
    """The file of the batch's shared-memory block."""
    assert batch._workers is not None
    return f"/dev/shm/{batch._workers.memory.name}"


def _mapped_block(pid: int) -> str:
    """The shared-memory block process `pid` maps (a worker maps its batch's)."""
    with open(f"/proc/{pid}/maps", encoding="ascii") as fh:
        (block,) = {line.split()[-1] for line in fh if "/dev/shm/psm_" in line}
    return block


def _alive(pid: int) -> bool:
    """Whether process `pid` runs (a zombie, dead but not yet reaped, counts as ended)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as fh:
            return fh.read().rpartition(")")[2].split()[0] != "Z"
    except FileNotFoundError:
        return False


BROKEN_AND_REPAIRED = (Breakdown(robot=1, at_s=40.0, repair_after_s=90.0), Breakdown(4, 100.0))
STEPPING = [
    pytest.param({"preset": "dahl2004", "max_sim_time_s": 300.0}, id="dahl2004-events"),
    pytest.param(
        {
            "preset": "dahl2004",
            "max_sim_time_s": 120.0,
            "decision_interval_s": 1.0,
            "breakdowns": BROKEN_AND_REPAIRED,
        },
        id="dahl2004-1s-breakdowns",
    ),
    pytest.param(
        {
            "scenario": "three_circuits",
            "max_sim_time_s": 400.0,
            "observation_mode": "rich",
            "observation_format": "box",
        },
        id="three_circuits-rich-box",
    ),
    pytest.param(
        {
            "scenario": "bad_start",
            "max_sim_time_s": 120.0,
            "decision_interval_s": 1.0,
            "observation_mode": "paper_id",
        },
        id="bad_start-1s",
    ),
]


def plain_row(obs: dict[str, Any], infos: dict[str, Any], agents: list[str]) -> dict[str, Any]:
    """One plain env's observations and infos as the batch lays them out, from its dicts."""
    first = obs[agents[0]]
    boxed = not isinstance(first, dict)
    row = {
        "observations": np.stack([obs[a] if boxed else obs[a]["observation"] for a in agents]),
        "action_mask": np.stack(
            [infos[a]["action_mask"] if boxed else obs[a]["action_mask"] for a in agents]
        ),
    }
    for key in infos[agents[0]]:
        if key != "action_mask":
            row[key] = np.array([infos[a][key] for a in agents])
    return row


def assert_row(found: dict[str, np.ndarray], e: int, expected: dict[str, Any]) -> None:
    for key, value in expected.items():
        assert np.array_equal(found[key][e], value), key
        assert found[key].dtype == value.dtype, key


@pytest.mark.parametrize("kwargs", STEPPING)
def test_every_arena_is_the_plain_env_with_its_spawned_seed_step_for_step(
    kwargs: dict[str, Any],
) -> None:
    """Arena e of the batch is `make_env` reset with the e-th seed spawned from the batch's seed:
    the same observations, masks, rewards, truncations and every info number, step after step,
    through breakdowns and repairs and across an episode's end (same-step autoreset)."""
    n_envs, seed = 2, 11
    envs = [make_env(**kwargs) for _ in range(n_envs)]
    agents = envs[0].possible_agents
    spawned = np.random.SeedSequence(seed).spawn(n_envs)
    plain = [env.reset(seed=int(s.generate_state(1)[0])) for env, s in zip(envs, spawned)]
    rng = np.random.default_rng(seed)
    ended = broken = 0
    with BatchedArenaEnv(n_envs, env_kwargs=kwargs) as batch:
        obs, infos = batch.reset(seed=seed)
        found = {"observations": obs, **infos}
        for _ in range(160):
            for e in range(n_envs):
                assert_row(found, e, plain_row(*plain[e], agents))
            actions = rng.integers(0, batch.n_circuits, (n_envs, len(agents)))
            step = batch.step(actions)
            found = {"observations": step.observations, **step.infos}
            for e, env in enumerate(envs):
                chosen = {
                    a: int(actions[e, i])
                    for i, a in enumerate(agents)
                    if plain[e][1][a]["action_required"]
                }
                o, rewards, _, truncations, i = env.step(chosen)
                assert step.rewards[e].tolist() == [rewards[a] for a in agents]
                assert bool(step.truncated[e]) == truncations[agents[0]]
                broken += sum(info["broken"] for info in i.values())
                plain[e] = (o, i)
                if not env.agents:
                    ended += 1
                    final = {"observations": step.infos["final_obs"], **step.infos["final_info"]}
                    assert_row(final, e, plain_row(o, i, agents))
                    plain[e] = env.reset()
    assert ended >= n_envs  # every arena crossed an episode's end
    assert broken > 0 or "breakdowns" not in kwargs
