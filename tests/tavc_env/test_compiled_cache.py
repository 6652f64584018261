"""The compiled controller on a read-only install (issue 12, item 4): numba caches the compiled
controller next to the source (`__pycache__`), in `NUMBA_CACHE_DIR` or in the user's cache folder.
A user who may write none of them (a package installed by root, run by someone else) once got a
`RuntimeError: cannot cache function ...: no locator available` at `import tavc_env`; now the
controller is compiled without a cache, with one warning naming the folders.

The test runs a short episode in a child process as `nobody`, with `NUMBA_CACHE_DIR` and `HOME`
pointing at read-only folders and the package's `__pycache__` owned by root. The child keeps one
capability, CAP_DAC_READ_SEARCH (read any file, search any folder, write nothing more), only so
that it can reach an interpreter installed under /root (pyenv); it cannot write anything `nobody`
cannot. Skipped unless the tests run as root with util-linux's `setpriv`.
"""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import tavc_env

NOBODY = 65534
ROOT = Path(tavc_env.__file__).resolve().parent.parent

CHILD = """
import json, os, sys, warnings
warnings.simplefilter("always")
with warnings.catch_warnings(record=True) as caught:
    import tavc_env
import numpy as np
writable = os.access(os.path.join(os.path.dirname(tavc_env.__file__), "engine", "__pycache__"),
                     os.W_OK)
env = tavc_env.parallel_env(preset="dahl2004")
obs, infos = env.reset(seed=5)
for _ in range(30):
    actions = {a: i % 2 for i, a in enumerate(env.agents) if infos[a]["action_required"]}
    obs, rewards, terms, truncs, infos = env.step(actions)
print(json.dumps({
    "uid": os.getuid(),
    "pycache_writable": writable,
    "warnings": [f"{w.category.__name__}: {w.message}" for w in caught],
    "time_s": env.sim_time_s,
    "positions": env.snapshot().positions.tolist(),
}))
"""


def _episode() -> tuple[float, np.ndarray]:
    env = tavc_env.parallel_env(preset="dahl2004")
    _, infos = env.reset(seed=5)
    for _ in range(30):
        actions = {a: i % 2 for i, a in enumerate(env.agents) if infos[a]["action_required"]}
        _, _, _, _, infos = env.step(actions)
    return env.sim_time_s, env.snapshot().positions


@pytest.fixture
def read_only_folder() -> Iterator[Path]:
    """A folder everyone may read and nobody but root may write (pytest's tmp_path is root's
    alone, so the folder lives directly in the system's temporary folder)."""
    folder = Path(tempfile.mkdtemp(prefix="tavc-readonly-"))
    folder.chmod(0o555)
    try:
        yield folder
    finally:
        folder.chmod(0o755)
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("setpriv") is None,
    reason="needs root (to become nobody) and util-linux setpriv",
)
def test_controller_runs_and_warns_when_no_cache_folder_is_writable(
    read_only_folder: Path,
) -> None:
    cache = read_only_folder / "numba-cache"
    cache.mkdir()
    cache.chmod(0o555)
    env = {
        "PATH": os.environ.get("PATH", "/usr/bin:/bin"),
        "HOME": str(read_only_folder),  # the user-wide cache (~/.cache/numba) is not writable
        "XDG_CACHE_HOME": str(read_only_folder),
        "NUMBA_CACHE_DIR": str(cache),
        "PYTHONPATH": str(ROOT),
        "PYTHONDONTWRITEBYTECODE": "1",
    }
    command = [
        "setpriv",
        f"--reuid={NOBODY}",
        f"--regid={NOBODY}",
        "--clear-groups",
        "--inh-caps=+dac_read_search",
        "--ambient-caps=+dac_read_search",
        sys.executable,
        "-c",
        CHILD,
    ]
    done = subprocess.run(
        command, env=env, cwd=read_only_folder, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["uid"] == NOBODY
    assert not report["pycache_writable"]
    cache_warnings = [w for w in report["warnings"] if "numba cannot write its cache" in w]
    assert len(cache_warnings) == 1, report["warnings"]
    assert str(cache) in cache_warnings[0]
    assert "__pycache__" in cache_warnings[0]
    # compiled without the cache, the controller drives the robots exactly as the cached one
    time_s, positions = _episode()
    assert report["time_s"] == time_s
    assert np.array_equal(np.array(report["positions"]), positions)


def test_compiled_functions_call_only_compiled_functions_of_their_own_file() -> None:
    """numba renews a function's on-disk cache when its own source file changes, not when a
    compiled function it calls in another file does: the cached caller would keep the old
    callee's code. So every compiled function of the engine calls compiled functions (and
    intrinsics) of its own file only."""
    from numba.core.dispatcher import Dispatcher
    from numba.core.extending import _Intrinsic

    import tavc_env.engine
    import tavc_env.engine.navigation as navigation

    modules = [
        importlib.import_module(f"tavc_env.engine.{m.name}")
        for m in pkgutil.iter_modules(tavc_env.engine.__path__)
    ]
    callers = [v for mod in modules for v in vars(mod).values() if isinstance(v, Dispatcher)]
    assert navigation.run_ticks in callers
    for caller in callers:
        func = caller.py_func
        for name in func.__code__.co_names:
            callee = func.__globals__.get(name)
            if isinstance(callee, Dispatcher):
                assert callee.py_func.__module__ == func.__module__, (func.__name__, name)
            elif isinstance(callee, _Intrinsic):
                assert callee._defn.__module__ == func.__module__, (func.__name__, name)
