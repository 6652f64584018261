"""Damaged files and run-folder slots, planted the way a careless or hostile user would, and a
guard that turns a hang into a failure.

* `no_hang(seconds)`: a block that fails with `Hang` (a BaseException, so no `except Exception`
  of the code under test swallows it) when it runs longer than `seconds` (SIGALRM; main thread);
* `plant(path, how, raw)`: replace `path` by one of `DAMAGES` made from `raw` (the bytes a good
  file there holds), a reader must refuse every one of them ("keep" and "link" are read).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

# Not regular files: a reader must refuse them before reading a byte (a FIFO or /dev/zero would
# block or read forever otherwise). A link to a good copy ("link", which `plant` makes too) is not
# among them: it is read, as git-annex, DVC and DataLad keep files.
NOT_FILES = ("folder", "dangling_link", "dev_zero", "fifo")
# Regular files a reader must refuse: garbled or truncated bytes, JSON that is not an object, a
# value that is not finite under a valid checksum, an integer too long to convert, too large.
BAD_FILES = ("garbled", "truncated", "list", "nan", "infinity", "huge_int", "too_large")
DAMAGES = NOT_FILES + BAD_FILES


class Hang(BaseException):
    """The code under test ran past its `no_hang` bound."""


@contextlib.contextmanager
def no_hang(seconds: float) -> Iterator[None]:
    """Fail with `Hang` if the block takes longer than `seconds` (a blocking open or read is
    interrupted: the handler raises, so the call is not retried)."""

    def alarm(signum: int, frame: Any) -> None:
        raise Hang(f"still running after {seconds:g} s: a read blocked or ran away")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _resealed(raw: bytes, value: Any) -> bytes:
    """`raw` (a record with a checksum, or any JSON object) with its first number field set to
    `value` and its checksum recomputed the way the package computes it: damage no checksum
    catches."""
    data = json.loads(raw)
    data.pop("checksum", None)
    body = data.get("result", data) if isinstance(data.get("result"), dict) else data
    key = next(
        (k for k, v in body.items() if isinstance(v, (int, float)) and not isinstance(v, bool)),
        None,
    )
    body[key or "planted"] = value
    if "schema" in data:
        canonical = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=True)
        data["checksum"] = hashlib.sha256(canonical.encode()).hexdigest()
    return json.dumps(data, allow_nan=True).encode()


def plant(path: Path, how: str, raw: bytes, limit: int = 64 * 1024 * 1024) -> None:
    """Replace whatever is at `path` by the damage `how` (one of `DAMAGES`, or "keep" to write
    `raw` itself), made from `raw`; `limit` is the reader's size bound ("too_large" is a sparse
    file one byte over it)."""
    if os.path.lexists(path):
        if path.is_dir() and not path.is_symlink():
            raise ValueError(f"{path} is a folder already; plant into a fresh slot")
        path.unlink()
    if how == "keep":
        path.write_bytes(raw)
    elif how == "folder":
        path.mkdir()
        (path / "inside.json").write_bytes(raw)
    elif how == "dangling_link":
        path.symlink_to(path.parent / f".{path.name}.nowhere")
    elif how == "link":  # to a good copy: read through (git-annex, DVC, DataLad)
        target = path.parent / f".{path.name}.target"
        target.write_bytes(raw)
        path.symlink_to(target)
    elif how == "dev_zero":
        path.symlink_to("/dev/zero")
    elif how == "fifo":
        os.mkfifo(path)
    elif how == "garbled":
        path.write_bytes(raw[: len(raw) // 2] + b"\x00\xff}" + raw[len(raw) // 2 :])
    elif how == "truncated":
        path.write_bytes(raw[: max(len(raw) - 7, 0)])
    elif how == "list":
        path.write_bytes(b"[]")
    elif how == "nan":
        path.write_bytes(_resealed(raw, float("nan")))
    elif how == "infinity":
        path.write_bytes(_resealed(raw, float("inf")))
    elif how == "huge_int":  # json.dumps itself refuses to write it: planted as text
        sentinel = b"7177717771777"
        path.write_bytes(_resealed(raw, int(sentinel)).replace(sentinel, b"9" * 5000, 1))
    elif how == "too_large":
        with open(path, "wb") as file:
            file.truncate(limit + 1)  # sparse: no disk used
    else:
        raise ValueError(f"how = {how!r} is invalid; allowed: {list(DAMAGES)} or 'keep'")
