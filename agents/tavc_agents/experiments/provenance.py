"""Where results come from: the machine, software versions, git commit and command of a run, and
sweeps that record them.

A study's report starts with the provenance of the run that *computed* its trials. It is saved as
`provenance.json` beside the report whenever a run computes at least one trial, and read back
when every trial is resumed from disk, so a report regenerated from saved trials states where
they came from and comes out byte for byte as before.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import stat
import subprocess
import sys
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, TypeVar

from tavc_agents.experiments.files import MIB, CorruptFileError, kind_of, read_json, write_text

PROVENANCE_FILE = "provenance.json"
PROVENANCE_MAX_BYTES = 1 * MIB  # a saved one is about 1 KiB


def _checkout() -> Path | None:
    # agents/tavc_agents/experiments/provenance.py in a checkout; site-packages/... in a wheel
    root = Path(__file__).resolve().parents[3]
    return root if (root / "pyproject.toml").is_file() and (root / "benchmarks").is_dir() else None


CHECKOUT = _checkout()
"""The source checkout the package runs from (an editable install, or the tests), or None when it
is installed from a wheel: only a checkout has a git commit and the committed reference results."""
_DISTRIBUTIONS = ("numpy", "scipy", "pymunk", "numba", "pettingzoo", "gymnasium")


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _ram_gib() -> float | None:
    try:
        with open("/proc/meminfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return round(int(line.split()[1]) / 1024**2, 1)
    except OSError:
        pass
    return None


def _version(distribution: str) -> str | None:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


def _git(*args: str) -> str | None:
    if CHECKOUT is None or not (CHECKOUT / ".git").exists():
        return None
    try:
        out = subprocess.run(
            ["git", *args],
            cwd=CHECKOUT,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def run_metadata(**extra: Any) -> dict[str, Any]:
    """Machine, software versions, git state, UTC time and the exact command line of this run."""
    commit = _git("rev-parse", "HEAD")
    # Dirty means changed code or docs; result files written by this or a concurrent run do not
    # count: the reference results and the reference data shipped in the package (the TAVC models
    # that `tavc_model --update-reference` writes).
    status = _git(
        "status",
        "--porcelain",
        "--",
        ".",
        ":(exclude)benchmarks/results",
        ":(exclude)agents/tavc_agents/data",
    )
    versions = {"python": platform.python_version()}
    versions.update({name: _version(name) for name in _DISTRIBUTIONS})  # type: ignore[misc]
    versions["tavc_env"] = _version("tavc-env")  # type: ignore[assignment]
    meta: dict[str, Any] = {
        "timestamp_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "cwd": os.getcwd(),
        "machine": {
            "platform": platform.platform(),
            "cpu_model": _cpu_model(),
            "cores": os.cpu_count(),
            "ram_gib": _ram_gib(),
        },
        "versions": versions,
        "git": {"commit": commit, "dirty": None if status is None else bool(status)},
    }
    meta.update(extra)
    return meta


def load_provenance(folder: str | Path) -> dict[str, Any] | None:
    """The provenance saved in `folder`, or None if there is none; a `CorruptFileError` naming
    the file, in one line, if it is not a regular file holding a JSON object (read safely:
    `tavc_env.safe_files`)."""
    path = Path(folder) / PROVENANCE_FILE
    if not os.path.lexists(path):
        return None
    data = read_json(path, PROVENANCE_MAX_BYTES, "provenance record")
    if not isinstance(data, dict):
        raise CorruptFileError(
            f"{path} holds {type(data).__name__}, not a provenance record (a JSON object); "
            "allowed: the provenance.json this package writes (remove it and run again to have a "
            "new one written)"
        )
    return data


def replaceable_provenance(folder: Path) -> CorruptFileError | None:
    """Check `folder`'s provenance before any job runs: None if it is absent or reads; the error
    if it is a damaged regular file (a run replaces it with its own); raised if it is anything
    else (a folder, a FIFO, a link, a device), which a run cannot replace without deleting it."""
    path = folder / PROVENANCE_FILE
    try:
        load_provenance(folder)
    except CorruptFileError as error:
        mode = path.lstat().st_mode
        if not stat.S_ISREG(mode):
            raise CorruptFileError(
                f"{path} is {kind_of(mode)}, not a regular file; allowed: a provenance.json this "
                "package wrote, or none (remove it and run again)"
            ) from None
        return error
    return None


def save_provenance(folder: str | Path, meta: Mapping[str, Any]) -> Path:
    """Write `meta` as `folder`/provenance.json (safely: see `tavc_agents.experiments.files`)."""
    path = Path(folder) / PROVENANCE_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_text(path, json.dumps(meta, indent=2) + "\n")


J = TypeVar("J")
R = TypeVar("R")
