"""N arenas stepped together, in worker processes, with every result stacked into arrays.

`BatchedArenaEnv(n_envs, workers=w, env_kwargs={...})` holds `n_envs` copies of the arena (each
built by `make_env(**env_kwargs)`, by default `tavc_env.arena.make_env`: a scenario or a preset),
split into `w` contiguous groups, one per worker process (`workers=0`: all in this process, the
cheapest per decision; workers only to use more cores). A step sends each worker its groups'
actions and returns, with `N = n_envs` and `n` robots:

- `observations`: `(N, n, k)` float32, the env's observation vector of every robot;
- `rewards`: `(N, n)` float64; `terminated`, `truncated`: `(N,)` bool (a whole arena ends at once);
- `infos`: a dict of arrays: every info field of the env, `(N, n)` (`action_required` is who must
  decide next, `elapsed_s`, `task_time_s`, `sim_time_s`, ...), and `action_mask` `(N, n, m)` int8.
  `BatchedStep.must_decide` and `.action_masks` name the two a loop needs.

Two calls are the whole API: `reset(seed) -> (observations, infos)` and `step(actions) ->
BatchedStep`. No per-agent dicts are built on the way: each arena steps through the env's own
`ArenaEnv.advance_choices` (the arena part of its `step`), and a group's observations, masks and
infos come from its engines' arrays at once (`tavc_env.env.arena_arrays`); arena `i` is the plain
env reset with the `i`-th spawned seed (below), step for step. The infos are the numbers of the
current env version (`tavc_arena_v1`) whatever `make_env` builds.

This is the layout of CleanRL's loops and of TorchRL's batched multi-agent tensors. Actions are an
integer array `(N, n)`; only entries of robots that must decide are read (others may hold anything,
e.g. a masked sample). **Autoreset, same step** (`AutoresetMode.SAME_STEP`): an arena whose episode
ends in a step is reset at once (its generator continues, so the run stays reproducible); the step
returns the new episode's first observations and infos (every robot deciding), the finished
episode's reward and `truncated`, and its last observations and infos in `infos["final_obs"]` and
`infos["final_info"]` (rows of other arenas zero), flagged by `infos["_final_obs"]` `(N,)`, as
Gymnasium names them. So no step is spent on a reset and every returned step has someone deciding.

`reset(seed)` derives one seed per arena from `seed` (`numpy.random.SeedSequence(seed).spawn`), so
the same seed gives the same arrays whatever the number of workers. Workers write their results
into one shared-memory block and answer through the pipe with a few bytes (the rows of finished
episodes, when there are any, are pickled): a round trip of one step's arrays takes about a third
of the time it takes pickled (`benchmarks/vector_throughput.py` measures both). An exception in a
worker is raised in this process as `WorkerError` with the worker's traceback, and the batch is
closed.

**Bounds and life cycle.** `n_envs` is at most `MAX_ENVS` (4096: about 0.2 MB and 2 ms to build
per `dahl2004` arena, so about 0.8 GB and 8 s, far more than two cores step usefully) and
`workers` at most `MAX_WORKERS` (256); more is refused before anything is built. Every wait on
the workers (building their arenas, `reset`, `step`) is bounded by `timeout_s` (default 600 s;
None waits forever): a worker that does not answer in time is named in a `WorkerTimeoutError`,
and the batch is closed (workers ended, shared memory freed). Workers exit when this process
closes them, and within about a second when it dies however it dies (even by SIGKILL, even while
they are still building their arenas): each watches its parent (its parent pid changes when the
parent ends). The shared-memory block is unlinked by `close`, by a finalizer that runs when the
batch is collected or this process exits, and, after a SIGKILL of this process, by
multiprocessing's resource tracker once the workers are gone.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import os
import pickle
import threading
import time
import traceback
import weakref
from collections.abc import Callable, Mapping, Sequence
from itertools import pairwise
from multiprocessing import shared_memory
from typing import Any, ClassVar, NamedTuple

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from tavc_env.arena import make_env as arena_env
from tavc_env.env import ArenaEnv, arena_arrays
from tavc_env.validation import is_integer, is_number, require

Arrays = dict[str, Any]  # field -> stacked array (and "final_info" -> such a dict)
EnvFactory = Callable[..., ArenaEnv[Any]]

MAX_ENVS = 4096
"""The most arenas a batch holds (see the module's docstring)."""
MAX_WORKERS = 256
"""The most worker processes a batch starts."""
DEFAULT_TIMEOUT_S = 600.0
"""How long a batch waits for a worker's answer by default (building its arenas, a reset or a
step; a cold numba cache compiles the controller within the first)."""
_WATCH_S = 0.25  # how often a worker checks that its parent is alive


def require_batch(n_envs: Any, env_kwargs: Any) -> None:
    """A ValueError unless `n_envs` is a batch size this package steps (1 to `MAX_ENVS`) and
    `env_kwargs` None or a mapping of arguments of the arenas' `make_env`."""
    require(
        is_integer(n_envs) and 1 <= n_envs <= MAX_ENVS,
        "n_envs",
        n_envs,
        f"an integer in [1, {MAX_ENVS}] (MAX_ENVS)",
    )
    require(
        env_kwargs is None or isinstance(env_kwargs, Mapping),
        "env_kwargs",
        env_kwargs,
        "None or a mapping of arguments of make_env",
    )


def require_circuits(actions: np.ndarray, deciding: np.ndarray, n_circuits: int) -> None:
    """A ValueError naming the first entry of `actions` `(N, n)` of a robot that must decide
    (`deciding`) that is not a circuit index (the other entries are not read)."""
    bad = deciding & ((actions < 0) | (actions >= n_circuits))
    if bad.any():
        e, i = (int(x) for x in np.argwhere(bad)[0])
        require(
            False,
            f"actions[{e}, {i}]",
            int(actions[e, i]),
            f"a circuit index in [0, {n_circuits - 1}] (robot {i} of arena {e} must decide)",
        )


def arena_seeds(seed: int | None, n_envs: int) -> list[int]:
    """One reset seed per arena of a batch, spawned from `seed` (`numpy.random.SeedSequence(seed)
    .spawn`; None: fresh entropy), so the same seed gives the same arenas however they are split."""
    children = np.random.SeedSequence(seed).spawn(n_envs)
    return [int(child.generate_state(1)[0]) for child in children]


def advance_arenas(
    envs: Sequence[ArenaEnv[Any]], actions: np.ndarray, deciding: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each arena's step (`ArenaEnv.advance_choices`) with the actions `(K, n)` of its robots that
    must decide (`deciding`, `(K, n)`; unchecked, the caller checked them); returns the rewards
    `(K, n)` and whether each arena's episode was truncated `(K,)`. The step's observations,
    masks and infos are then `arena_arrays`."""
    rewards = np.zeros(deciding.shape)
    truncated = np.zeros(len(envs), bool)
    for e, env in enumerate(envs):
        row = actions[e]
        choices = [(i, int(row[i])) for i in deciding[e].nonzero()[0].tolist()]
        rewards[e], truncated[e] = env.advance_choices(choices)
    return rewards, truncated


class WorkerError(RuntimeError):
    """An exception raised in a worker process; its message carries the worker's traceback."""


class WorkerTimeoutError(WorkerError):
    """A worker that did not answer within `timeout_s`; the batch was closed."""


class BatchedStep(NamedTuple):
    """What `BatchedArenaEnv.step` returns; unpacks as Gymnasium's five values."""

    observations: np.ndarray
    rewards: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    infos: Arrays

    @property
    def must_decide(self) -> np.ndarray:
        """`(N, n)` bool: the robots whose action the next step reads."""
        mask: np.ndarray = self.infos["action_required"]
        return mask

    @property
    def action_masks(self) -> np.ndarray:
        """`(N, n, m)` int8: the circuits each robot may choose (all, for a deciding robot)."""
        mask: np.ndarray = self.infos["action_mask"]
        return mask


class ArenaGroup:
    """Some arenas stepped in turn (`ArenaEnv.advance_choices`), every result built for all of
    them at once from their engines' arrays (`tavc_env.env.arena_arrays`), no per-agent dicts:
    the work of one worker (or of the in-process mode). Knows nothing of processes. Only the
    actions of robots that must decide are read, unchecked (`BatchedArenaEnv.step` checks
    them)."""

    def __init__(self, make_env: EnvFactory, env_kwargs: Mapping[str, Any], count: int) -> None:
        self.envs = [make_env(**env_kwargs) for _ in range(count)]
        self.agents = list(self.envs[0].possible_agents)
        self._deciding = np.zeros((count, len(self.agents)), bool)

    def reset(self, seeds: Sequence[int | None]) -> Arrays:
        for env, seed in zip(self.envs, seeds):
            env.reset(seed=seed)
        out = arena_arrays(self.envs, [False] * len(self.envs))
        self._deciding = out["action_required"].copy()  # the caller may write to its own
        return out

    def step(self, actions: np.ndarray) -> Arrays:
        count = len(self.envs)
        rewards, truncated = advance_arenas(self.envs, actions, self._deciding)
        out: Arrays = arena_arrays(self.envs, truncated.tolist())
        ended = truncated.nonzero()[0].tolist()
        if ended:  # same-step autoreset; only the finished arenas' rows travel (most steps none)
            out["final"] = {key: value[ended] for key, value in out.items()}
            for e in ended:
                self.envs[e].reset()  # its generator continues
            fresh = arena_arrays([self.envs[e] for e in ended], [False] * len(ended))
            for key, value in fresh.items():
                out[key][ended] = value
        self._deciding = out["action_required"].copy()  # the caller may write to its own
        out.update(rewards=rewards, terminated=np.zeros(count, bool), truncated=truncated)
        out["_final"] = truncated.copy()
        return out

    def close(self) -> None:
        for env in self.envs:
            env.close()


_STEP_ONLY = ("rewards", "terminated", "truncated")
_STEP_FIELDS = (*_STEP_ONLY, "_final")  # what a reset does not write


Layout = list[tuple[str, str, tuple[int, ...]]]
"""The shared block's fields: name, dtype and the shape of one arena's entry."""


def _views(buffer: Any, layout: Layout, n_envs: int) -> dict[str, np.ndarray]:
    """Arrays `(n_envs, *shape)` of every field of `layout`, laid end to end in `buffer`."""
    views, offset = {}, 0
    for key, dtype, shape in layout:
        view = np.ndarray((n_envs, *shape), np.dtype(dtype), buffer=buffer, offset=offset)
        views[key] = view
        offset += view.nbytes
    return views


def _watch_parent(parent_pid: int) -> None:
    """In a worker: end this process as soon as the process that made the batch (`parent_pid`)
    is gone, whatever this process is doing (building arenas, stepping). The parent's death
    changes this process's parent pid (it is adopted by init or a subreaper); under `forkserver`
    the parent is the fork server, which ends when the batch's process does. A daemon thread."""
    first = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(_WATCH_S)
            gone = os.getppid() != first
            if not gone:
                try:
                    os.kill(parent_pid, 0)
                except ProcessLookupError:
                    gone = True
                except OSError:  # EPERM: it exists
                    pass
            if gone:
                os._exit(1)  # no clean-up: nobody is left to answer; the mapping goes with us

    threading.Thread(target=watch, name="tavc-parent-watch", daemon=True).start()


def _serve(
    connection: multiprocessing.connection.Connection,
    parent_end: multiprocessing.connection.Connection | None,
    make_env: EnvFactory,
    env_kwargs: Mapping[str, Any],
    arenas: tuple[int, int],
    block: tuple[str, Layout, int],
    parent_pid: int | None = None,
) -> None:
    """A worker: build arenas `arenas[0]` to `arenas[1] - 1`, then answer reset/step/close
    messages until told to close or until the parent's end of the pipe closes (the parent died);
    with `parent_pid`, a thread ends the worker at once when that process dies. Results go into
    the worker's rows of the shared block `block` (name, layout, arenas); only the rows of
    finished episodes travel through the pipe."""
    if parent_pid is not None:
        _watch_parent(parent_pid)
    if parent_end is not None:
        parent_end.close()  # a forked copy of the parent's end would keep the pipe open forever
    group: ArenaGroup | None = None
    memory = shared_memory.SharedMemory(name=block[0])
    views = {k: v[arenas[0] : arenas[1]] for k, v in _views(memory.buf, *block[1:]).items()}
    try:
        group = ArenaGroup(make_env, env_kwargs, arenas[1] - arenas[0])
        connection.send(("ok", None))
        while True:
            try:
                command, argument = connection.recv()
            except EOFError:
                break  # the parent is gone: nobody to answer
            if command == "close":
                connection.send(("ok", None))
                break
            result = group.reset(argument) if command == "reset" else group.step(argument)
            final = result.pop("final", None)
            for key, value in result.items():
                views[key][...] = value
            connection.send(("ok", final))
    except (KeyboardInterrupt, BrokenPipeError):
        pass  # interrupted with the parent, or the parent is gone: nothing to report to
    except BaseException:
        with contextlib.suppress(OSError, EOFError):  # the parent may be gone too
            connection.send(("error", traceback.format_exc()))
    finally:
        if group is not None:
            group.close()
        connection.close()
        views.clear()  # no view may outlive the mapping
        memory.close()


class _Workers:
    """The worker processes and their pipes; closing twice does nothing."""

    def __init__(
        self,
        make_env: EnvFactory,
        env_kwargs: Mapping[str, Any],
        spans: Sequence[tuple[int, int]],
        layout: Layout,
        start_method: str | None,
        timeout_s: float | None = None,
    ) -> None:
        context: Any = multiprocessing.get_context(start_method)  # typeshed's lacks Process
        n_envs = spans[-1][1]
        size = sum(v.nbytes for v in _views(None, layout, n_envs).values())
        self.timeout_s = timeout_s
        self.memory = shared_memory.SharedMemory(create=True, size=max(size, 1))
        self.views = _views(self.memory.buf, layout, n_envs)
        self.connections: list[multiprocessing.connection.Connection] = []
        self.processes: list[multiprocessing.process.BaseProcess] = []
        self.closed = False
        try:
            self._start(context, make_env, env_kwargs, spans, layout, n_envs)
            self.gather("build its arenas")  # every worker built them (or its error is raised)
        except BaseException:  # Ctrl-C included: no worker or shared block is left behind
            self.close(polite=False)
            raise

    def _start(
        self,
        context: Any,
        make_env: EnvFactory,
        env_kwargs: Mapping[str, Any],
        spans: Sequence[tuple[int, int]],
        layout: Layout,
        n_envs: int,
    ) -> None:
        for span in spans:
            parent_end, child_end = context.Pipe()
            process = context.Process(
                target=_serve,
                args=(
                    child_end,
                    parent_end,
                    make_env,
                    dict(env_kwargs),
                    span,
                    (self.memory.name, layout, n_envs),
                    os.getpid(),
                ),
                daemon=True,  # ended with this process if it exits without closing us
            )
            self.connections.append(parent_end)
            try:
                process.start()
            except (pickle.PicklingError, AttributeError, TypeError) as exc:
                raise ValueError(
                    f"make_env = {make_env!r} is invalid with start method "
                    f"{context.get_start_method()!r}; allowed: a module-level function (and "
                    f"picklable env_kwargs), which a new process can import ({exc})"
                ) from exc
            finally:
                child_end.close()
            self.processes.append(process)

    def send(self, messages: Sequence[tuple[str, Any]]) -> None:
        try:
            for connection, message in zip(self.connections, messages):
                connection.send(message)
        except OSError as exc:  # a worker is gone: its error (or its end) is what gather reports
            self.close(polite=False)
            raise WorkerError(f"a worker process ended unexpectedly ({exc!r})") from None

    def gather(self, doing: str = "answer") -> list[Any]:
        """Every worker's answer, in order. A worker error, or a worker that does not answer
        within `timeout_s` (`doing` says what it was asked to do), closes all and is raised."""
        n = len(self.connections)
        deadline = None if self.timeout_s is None else time.monotonic() + self.timeout_s
        answers: list[Any] = [None] * n
        errors: list[str] = []
        waiting = dict(enumerate(self.connections))
        while waiting:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            ready = multiprocessing.connection.wait(list(waiting.values()), timeout=left)
            if not ready:
                late = ", ".join(
                    f"worker {w} of {n} (pid {self.processes[w].pid})" for w in sorted(waiting)
                )
                self.close(polite=False)
                raise WorkerTimeoutError(
                    "".join(f"{e}\n" for e in errors)
                    + f"{late} did not {doing} within timeout_s = {self.timeout_s} s; the batch "
                    "is closed (its workers ended, its shared memory freed); allowed: a larger "
                    "timeout_s, or None to wait without a bound"
                )
            for w in [w for w, c in waiting.items() if c in ready]:
                try:
                    status, payload = waiting.pop(w).recv()
                except (EOFError, OSError) as exc:
                    status, payload = "error", f"the worker process ended unexpectedly ({exc!r})"
                if status == "error":
                    errors.append(f"worker {w} of {n} failed:\n{payload}")
                answers[w] = payload
        if errors:
            self.close(polite=False)
            raise WorkerError("\n".join(errors))
        return answers

    def close(self, polite: bool = True) -> None:
        """End the workers (asked first if `polite`, a frozen one terminated, then killed) and
        free the shared block; closing again does nothing."""
        if self.closed:
            return
        self.closed = True
        try:
            if polite:
                for connection in self.connections:
                    try:
                        connection.send(("close", None))
                        if connection.poll(5.0):  # a frozen worker does not answer
                            connection.recv()
                    except (OSError, EOFError):
                        pass
            for process in self.processes:
                process.join(timeout=5 if polite else 0.5)
                if process.is_alive():
                    process.terminate()
                    process.join(timeout=2)
                if process.is_alive():  # SIGTERM ignored or blocked
                    process.kill()
                    process.join(timeout=2)
        finally:
            for connection in self.connections:
                connection.close()
            self.views.clear()  # no view may outlive the mapping
            self.memory.close()
            with contextlib.suppress(FileNotFoundError):
                self.memory.unlink()


class BatchedArenaEnv:
    """`n_envs` arenas stepped together, results stacked (see the module's docstring).

    Args:
        n_envs: arenas in the batch (`N`).
        workers: worker processes, the arenas split among them as evenly as possible; 0 steps
            every arena in this process. Several arenas per worker spread the cost of the pipes.
        env_kwargs: arguments of `make_env` (e.g. `preset`, `max_sim_time_s`,
            `observation_mode`); every arena gets the same.
        make_env: builds one arena, an `ArenaEnv` (default `tavc_env.arena.make_env`, which takes a `scenario` or a `preset`; the twin's
            `twin_parallel_env` works too). With the `spawn` start method it must be importable
            (a module-level function), as multiprocessing sends it by name.
        start_method: multiprocessing's (`fork`, `spawn`, `forkserver`); None: the platform's
            default.
        timeout_s: the longest wait, in seconds, for the workers to build their arenas and to
            answer each `reset` and `step` (default 600); a worker that does not answer in time
            is a `WorkerTimeoutError` naming it, and the batch is closed. None: no bound.

    `n_envs` is at most `MAX_ENVS` and `workers` at most `MAX_WORKERS`.
    """

    metadata: ClassVar[dict[str, Any]] = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        n_envs: int,
        *,
        workers: int = 0,
        env_kwargs: Mapping[str, Any] | None = None,
        make_env: EnvFactory = arena_env,
        start_method: str | None = None,
        timeout_s: float | None = DEFAULT_TIMEOUT_S,
    ) -> None:
        require_batch(n_envs, env_kwargs)
        require(
            is_integer(workers) and 0 <= workers <= min(n_envs, MAX_WORKERS),
            "workers",
            workers,
            f"an integer in [0, min(n_envs = {n_envs}, {MAX_WORKERS})] (0: every arena in this "
            "process; MAX_WORKERS)",
        )
        require(
            timeout_s is None or (is_number(timeout_s) and timeout_s > 0),
            "timeout_s",
            timeout_s,
            "None (no bound) or a finite number of seconds > 0",
        )
        require(callable(make_env), "make_env", make_env, "a function returning an ArenaEnv")
        methods = multiprocessing.get_all_start_methods()
        require(
            start_method is None or start_method in methods,
            "start_method",
            start_method,
            f"None or one of {methods}",
        )
        kwargs = dict(env_kwargs or {})
        # one arena built here first: a bad argument is the env's own ValueError, raised here
        probe = make_env(**kwargs)
        require(
            isinstance(probe, ArenaEnv), "make_env", make_env, "a function returning an ArenaEnv"
        )
        layout = _layout(probe)
        self.n_envs = int(n_envs)
        self.workers = int(workers)
        self.possible_agents = list(probe.possible_agents)
        self.n_agents = len(self.possible_agents)
        self.n_circuits = probe.config.n_circuits
        vector = probe.observation_space(self.possible_agents[0])
        if isinstance(vector, spaces.Dict):
            vector = vector["observation"]
        assert isinstance(vector, spaces.Box)
        self.single_observation_space: spaces.Box = vector
        self.single_action_space = spaces.Discrete(self.n_circuits)
        self.observation_space = spaces.Box(
            np.broadcast_to(vector.low, (self.n_envs, self.n_agents, *vector.shape)),
            np.broadcast_to(vector.high, (self.n_envs, self.n_agents, *vector.shape)),
            dtype=np.float32,
        )
        self.action_space = spaces.MultiDiscrete(
            np.full((self.n_envs, self.n_agents), self.n_circuits)
        )
        probe.close()
        counts = [len(part) for part in np.array_split(np.arange(self.n_envs), max(workers, 1))]
        bounds = np.cumsum([0, *counts])
        self._spans = [(int(a), int(b)) for a, b in pairwise(bounds)]
        self._deciding: np.ndarray | None = None  # None until reset
        self._local: ArenaGroup | None = None
        self._workers: _Workers | None = None
        if workers == 0:
            self._local = ArenaGroup(make_env, kwargs, self.n_envs)
        else:
            timeout = None if timeout_s is None else float(timeout_s)
            self._workers = _Workers(make_env, kwargs, self._spans, layout, start_method, timeout)
            self._finalizer = weakref.finalize(self, self._workers.close)
        self.closed = False

    def reset(self, seed: int | None = None) -> tuple[np.ndarray, Arrays]:
        """Reset every arena: with `seed`, arena `i` from the `i`-th seed spawned from it; without,
        each continues its own stream (the first reset without a seed draws fresh entropy)."""
        self._check_open()
        require(
            seed is None or (is_integer(seed) and seed >= 0),
            "seed",
            seed,
            "None or an integer >= 0 (int or numpy integer; not bool, not float)",
        )
        seeds: list[int | None] = [None] * self.n_envs
        if seed is not None or self._deciding is None:
            seeds = list(arena_seeds(None if seed is None else int(seed), self.n_envs))
        out, _ = self._run("reset", [seeds[a:b] for a, b in self._spans])
        self._deciding = out["action_required"].copy()  # the caller may write to its own
        observations = out.pop("observations")
        return observations, out

    def step(self, actions: Any) -> BatchedStep:
        """Step every arena with `actions` `(N, n)` (integers; only deciding robots' are read)."""
        self._check_open()
        if self._deciding is None:
            raise ValueError("step() called before reset(); allowed: call reset() first")
        chosen = self._checked_actions(actions, self._deciding)
        out, finished = self._run("step", [chosen[a:b] for a, b in self._spans])
        self._deciding = out["action_required"].copy()  # the caller may write to its own
        rewards, terminated, truncated = (out.pop(k) for k in _STEP_ONLY)
        done = out.pop("_final")
        final = {key: np.zeros_like(value) for key, value in out.items()}
        if finished:  # the finished rows of every group, in arena order
            for key, value in final.items():
                value[done] = np.concatenate([part[key] for part in finished])
        observations = out.pop("observations")
        out["_final_obs"] = out["_final_info"] = done
        out["final_obs"] = final.pop("observations")
        out["final_info"] = final
        return BatchedStep(observations, rewards, terminated, truncated, out)

    @property
    def worker_pids(self) -> list[int]:
        """The process ids of the workers (none in-process)."""
        if self._workers is None:
            return []
        return [p.pid for p in self._workers.processes if p.pid is not None]

    def close(self) -> None:
        """Close every arena and end the workers; closing again does nothing."""
        if self.closed:
            return
        self.closed = True
        if self._workers is not None:
            self._finalizer()
        if self._local is not None:
            self._local.close()

    def __enter__(self) -> BatchedArenaEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- helpers ---------------------------------------------------------------------------------
    def _run(self, command: str, arguments: list[Any]) -> tuple[Arrays, list[Arrays]]:
        """Every group's results (copied out of the shared block), and the final rows of the
        groups in which an episode ended."""
        if self._local is not None:
            local = self._local.reset if command == "reset" else self._local.step
            out = local(arguments[0])
            return out, [out.pop("final")] if "final" in out else []
        assert self._workers is not None
        try:
            self._workers.send([(command, argument) for argument in arguments])
            finals = self._workers.gather(f"answer {command}()")
        except WorkerError:
            self.closed = True
            raise
        out = {
            key: view.copy()
            for key, view in self._workers.views.items()
            if command == "step" or key not in _STEP_FIELDS
        }
        return out, [final for final in finals if final is not None]

    def _check_open(self) -> None:
        if self.closed:
            raise ValueError("the batched env is closed; allowed: a new BatchedArenaEnv")

    def _checked_actions(self, actions: Any, deciding: np.ndarray) -> np.ndarray:
        """`actions` as an int64 array `(N, n)`, or a ValueError naming the first bad entry of a
        robot that must decide (the others are not read)."""
        shape = (self.n_envs, self.n_agents)
        array = np.asarray(actions)
        require(
            array.shape == shape and array.dtype.kind in "iu",
            "actions",
            f"array of shape {array.shape} and dtype {array.dtype}",
            f"an integer array of shape {shape}",
        )
        require_circuits(array, deciding, self.n_circuits)
        return array.astype(np.int64)


def _layout(probe: ArenaEnv[Any]) -> Layout:
    """The fields a step returns for one arena of `probe`'s kind (read from a reset of it), the
    widest first so that every field stays aligned in the shared block."""
    n = len(probe.possible_agents)
    probe.reset(seed=0)
    row = arena_arrays([probe], [False])
    fields = [(key, value.dtype.str, value.shape[1:]) for key, value in row.items()]
    fields += [("rewards", "<f8", (n,)), ("terminated", "|b1", ()), ("truncated", "|b1", ())]
    fields += [("_final", "|b1", ())]
    return sorted(fields, key=lambda field: -np.dtype(field[1]).itemsize)
