"""Reading files safely: only a regular file, never blocking, never more than a bound.

Every file the package reads (stored trials, provenance, manifests, reports, models, task YAML,
network files) goes through `read_bytes`, `read_text` or `read_json`. A path is read only if it
is a regular file, or a symbolic link to one (git-annex, DVC and DataLad keep results as links into
their stores), of at most `limit` bytes: it is looked at with `stat` (a link to a FIFO, a device, a
folder, or to nothing is refused, naming what it points to), opened with `O_NONBLOCK` (a FIFO
swapped in after the look does not block the open), the open descriptor is checked again with
`fstat` (regular, size within the bound), and at most `limit + 1` bytes are read (a file growing
past its bound is caught too). Anything else (a folder, a FIFO, a device such as `/dev/zero`, a
socket, a dangling link, a file too large or unreadable, text that is not UTF-8, JSON that is
garbled, nested too deeply, holds a number Python refuses to convert or a value that is not
finite) raises `CorruptFileError`, a ValueError naming the file and what it is, in one line.

Files are written through `atomic_path`: a new file made with mode 0o666 less the umask (as
`open` makes one), so a colleague sharing the folder reads it as they read the user's other files.

Public, at the lowest layer, so that the env's own readers (the BenchMARL task files) can use it
as well as the agent library; `tavc_agents.experiments.files` re-exports it with the record format
on top.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import secrets
import stat
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

KIB = 1024
MIB = 1024 * KIB


class CorruptFileError(ValueError):
    """A file that cannot be trusted: not a regular file, too large, unreadable, truncated, not
    JSON, not finite, edited, of the wrong schema. The message names the file, in one line."""


def kind_of(mode: int) -> str:
    """What a file of `st_mode` `mode` is, in words ("a FIFO", "a folder", ...)."""
    for test, name in (
        (stat.S_ISLNK, "a symbolic link"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISREG, "a regular file"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def _refuse(path: Path, what: str, why: str, allowed: str = "") -> CorruptFileError:
    return CorruptFileError(
        f"{path} {why}; allowed: {allowed or f'a {what} as this package writes it'}"
    )


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split())


def read_bytes(path: str | Path, limit: int, what: str = "file") -> bytes:
    """The bytes of the regular file `path` (at most `limit` bytes; `what` it should be, for the
    message): see the module for what is refused."""
    path = Path(path)
    try:
        mode = path.lstat().st_mode
    except FileNotFoundError:
        raise _refuse(path, what, "does not exist") from None
    except OSError as error:
        raise _refuse(path, what, f"cannot be looked at ({_one_line(error)})") from None
    link = ""
    if stat.S_ISLNK(mode):  # read through, if it ends at a regular file
        try:
            mode = path.stat().st_mode
        except OSError as error:  # dangling, a loop, a target that cannot be looked at
            raise _refuse(
                path,
                what,
                f"is a symbolic link to {_target(path)!r}, which cannot be read "
                f"({_one_line(error)})",
                f"a {what} that is a regular file or a link to one",
            ) from None
        link = "a symbolic link to "
    if not stat.S_ISREG(mode):
        raise _refuse(
            path,
            what,
            f"is {link}{kind_of(mode)}, not a regular file",
            f"a {what} that is a regular file or a link to one",
        )
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags | getattr(os, "O_CLOEXEC", 0))
    except OSError as error:  # unreadable, removed after the look, ...
        raise _refuse(path, what, f"cannot be opened ({_one_line(error)})") from None
    with os.fdopen(fd, "rb", buffering=0) as file:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):  # swapped after the look
            raise _refuse(
                path,
                what,
                f"is {kind_of(info.st_mode)}, not a regular file",
                f"a {what} that is a regular file or a link to one",
            )
        if info.st_size > limit:
            raise _refuse(
                path,
                what,
                f"holds {info.st_size} bytes, more than the {limit} allowed",
                f"a {what} of at most {limit} bytes",
            )
        chunks: list[bytes] = []
        size = 0
        try:
            while size <= limit:  # a file growing while read stops one byte past its bound
                chunk = file.read(limit + 1 - size)
                if not chunk:
                    break
                chunks.append(chunk)
                size += len(chunk)
        except OSError as error:
            raise _refuse(path, what, f"cannot be read ({_one_line(error)})") from None
    if size > limit:
        raise _refuse(
            path,
            what,
            f"grew past the {limit} bytes allowed while it was read",
            f"a {what} of at most {limit} bytes",
        )
    return b"".join(chunks)


def _target(path: Path) -> str:
    try:
        return os.readlink(path)
    except OSError:  # pragma: no cover - swapped after the look
        return "?"


def read_text(path: str | Path, limit: int, what: str = "file") -> str:
    """The UTF-8 text of the regular file `path` (see `read_bytes`)."""
    raw = read_bytes(path, limit, what)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise _refuse(Path(path), what, f"is not UTF-8 text ({error}): garbled") from None


class _NotFinite(ValueError):
    """A JSON constant (NaN, Infinity, -Infinity) where only finite numbers are allowed."""


def _no_constant(name: str) -> Any:
    raise _NotFinite(name)


def _nan_only(name: str) -> float:
    if name != "NaN":
        raise _NotFinite(name)
    return math.nan


def parse_json(path: str | Path, raw: bytes | str, what: str = "file", nan: bool = False) -> Any:
    """`raw` (the content of `path`) decoded as JSON whose numbers are all finite (NaN too is
    allowed with `nan`: some records use it for "undefined"); a `CorruptFileError` naming `path`
    otherwise."""
    path = Path(path)
    try:
        data = json.loads(raw, parse_constant=_no_constant if not nan else _nan_only)
        where = first_not_finite(data, nan)  # a literal too large for a float reads as infinity
    except _NotFinite as error:
        raise _refuse(path, what, f"holds the value {error} (not a finite number)") from None
    except RecursionError:
        # no file this package writes comes near the limit: a damaged or planted file
        raise _refuse(
            path, what, f"is nested deeper than the recursion limit ({sys.getrecursionlimit()})"
        ) from None
    except UnicodeDecodeError as error:
        raise _refuse(path, what, f"is not UTF-8 text ({error}): garbled") from None
    except ValueError as error:  # not JSON, or an integer too long to convert
        if "integer string conversion" in str(error):  # CPython's int-string limit
            raise _refuse(
                path, what, f"holds an integer too long to convert ({_one_line(error)})"
            ) from None
        raise _refuse(
            path, what, f"is not valid JSON ({_one_line(error)}): truncated or garbled"
        ) from None
    if where is not None:
        raise _refuse(path, what, f"holds a value that is not a finite number at {where}")
    return data


def first_not_finite(data: Any, nan: bool = False, where: str = "") -> str | None:
    """Where in `data` (JSON-like) the first float that is not finite is (`[k]` and `.key`
    steps; NaN passes with `nan`), or None. Recursive: call it on data that was decoded (or will
    be encoded) within the recursion limit."""
    if isinstance(data, float):
        if math.isfinite(data) or (nan and math.isnan(data)):
            return None
        return where or "the top"
    if isinstance(data, dict):
        items: Any = ((f"{where}.{k}", v) for k, v in data.items())
    elif isinstance(data, (list, tuple)):
        items = ((f"{where}[{k}]", v) for k, v in enumerate(data))
    else:
        return None
    for at, value in items:
        found = first_not_finite(value, nan, at)
        if found is not None:
            return found
    return None


def read_json(path: str | Path, limit: int, what: str = "file", nan: bool = False) -> Any:
    """The JSON in the regular file `path`, its numbers finite (see `read_bytes`, `parse_json`)."""
    return parse_json(path, read_bytes(path, limit, what), what, nan)


# -- writing ------------------------------------------------------------------------------------
def check_writable(path: str | Path) -> Path:
    """`path` as a Path, after checking that writing it replaces at most a regular file, that its
    folder exists, and that a file can be made there (a temporary one is made and removed: a
    name too long, a read-only or virtual file system such as /proc, a full disk are caught); a
    ValueError naming the path otherwise, in one line (call it before long work)."""
    path = _replaceable(path)
    try:
        _new_file(path).unlink()
    except OSError as error:
        raise ValueError(
            f"{path} cannot be written ({error.strerror or _one_line(error)}); allowed: a file "
            "in a folder this user can write"
        ) from None
    return path


def _replaceable(path: str | Path) -> Path:
    path = Path(path)
    try:
        mode: int | None = path.lstat().st_mode
    except FileNotFoundError:
        mode = None
    except OSError as error:  # a name too long, a folder in the path that cannot be searched
        raise ValueError(
            f"{path} cannot be written ({error.strerror or _one_line(error)}); allowed: a file "
            "in a folder this user can write"
        ) from None
    if mode is not None and not stat.S_ISREG(mode):
        raise ValueError(
            f"{path} is {kind_of(mode)}; refusing to replace it with a regular file; allowed: a "
            "new path or an existing regular file"
        )
    if not path.parent.is_dir():
        raise ValueError(
            f"{path}: the folder {path.parent} does not exist; allowed: an existing folder"
        )
    return path


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path to write into; on leaving the block it is flushed to disk and renamed
    over `path` (on an error it is removed and `path` is untouched). The file is made with mode
    0o666 less the process's umask, as `open` makes a new file (`mkstemp` would make it 0o600:
    readable by its owner only)."""
    path = _replaceable(path)
    tmp = _new_file(path)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    sync_folder(path.parent)


def temporary_name(path: Path) -> Path:
    """A fresh name for a temporary file beside `path`: `.<name>.<random>.tmp<suffix>` (the same
    ending as the destination, for writers that infer a format from it, such as figures)."""
    return path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp{path.suffix}")


def is_temporary(name: str, of: str) -> bool:
    """Whether `name` is a temporary file `atomic_path` made for a file named `of`."""
    return name.startswith(f".{of}.") and ".tmp" in name[len(of) + 2 :]


def _new_file(path: Path) -> Path:
    """Make a new empty file beside `path` (mode 0o666 less the umask, never an existing one)."""
    for _ in range(100):
        tmp = temporary_name(path)
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        except FileExistsError:  # pragma: no cover - 32 random bits taken
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(f"no free temporary name beside {path}")  # pragma: no cover


def sync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # pragma: no cover - folders that cannot be opened (some platforms)
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)
