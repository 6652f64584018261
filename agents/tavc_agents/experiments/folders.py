"""Run folders: checked before any work starts, and locked by the sweep that writes them.

`check_out_folder` refuses, in one line, an output folder that a run could not write: an existing
file (or a symbolic link to one), a dangling symbolic link, a name longer than the file system
allows, or a folder that this process may not write (`os.access`: a superuser passes it except
on a read-only file system, and then really can write; a full disk is not seen here, but the
sweep stops at its first refused save).

`hold_folder` keeps `<folder>/.tavc.lock` locked (`fcntl.flock`, with the holder's pid written in
it) for as long as a sweep writes the folder, so a second sweep on the same folder is refused at
once, naming that pid, instead of both writing trials and reports over each other. The lock is
advisory: it keeps this package's sweeps apart, not other programs. It is released when the
holder ends, even by SIGKILL (the kernel drops it), and the file stays (removing it would let
a third sweep lock a new file while a second still holds the old one); git ignores it.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import stat
from collections.abc import Iterator
from pathlib import Path

LOCK_FILE = ".tavc.lock"
_held: dict[tuple[int, int], tuple[int, int]] = {}
"""Folders this process holds: (device, inode) -> (lock file descriptor, how many holders), so a
study that locks its run folder can run sweeps that lock it again."""


class FolderError(ValueError):
    """An output folder that a run cannot use (refused before any work, in one line)."""


class FolderInUseError(FolderError):
    """Another sweep holds the folder's lock."""


def check_out_folder(folder: str | Path, option: str = "--out") -> Path:
    """`folder` as a Path, after checking that a run can make and write it (see the module); a
    `FolderError` naming `option`, the folder and what is wrong otherwise."""
    text = os.fspath(folder)
    allowed = "allowed: a folder this user can write (existing, or new in one that is)"
    if text == "":
        raise FolderError(f"{option} '' is invalid: an empty name; {allowed}")
    path = Path(text)
    name_max = _limit(path, "PC_NAME_MAX", 255)
    for part in path.parts:
        if len(os.fsencode(part)) > name_max:
            raise FolderError(
                f"{option} {text!r} is invalid: the name {part[:20]!r}... is "
                f"{len(os.fsencode(part))} bytes long, over this file system's {name_max}; "
                f"{allowed}"
            )
    path_max = _limit(path, "PC_PATH_MAX", 4096)
    if len(os.fsencode(os.path.abspath(text))) >= path_max:
        raise FolderError(f"{option} {text!r} is invalid: longer than {path_max} bytes; {allowed}")
    existing = path
    while not os.path.lexists(existing) and existing != existing.parent:
        existing = existing.parent
    if existing.is_symlink() and not existing.exists():
        raise FolderError(
            f"{option} {text!r} is invalid: {existing} is a symbolic link to "
            f"{os.readlink(existing)!r}, which does not exist; {allowed}"
        )
    if not existing.is_dir():
        raise FolderError(f"{option} {text!r} is invalid: {existing} is not a folder; {allowed}")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise FolderError(
            f"{option} {text!r} is invalid: this user may not write in {existing} (its "
            f"permissions, or a read-only file system); {allowed}"
        )
    return path


def _limit(path: Path, name: str, default: int) -> int:
    """A file system limit (`os.pathconf`) at the nearest existing ancestor of `path`."""
    existing = Path(os.path.abspath(path))
    while not os.path.exists(existing) and existing != existing.parent:
        existing = existing.parent
    try:
        return os.pathconf(existing, name)
    except (OSError, ValueError):
        return default


@contextlib.contextmanager
def hold_folder(folder: str | Path) -> Iterator[Path]:
    """Make `folder` if needed and hold its lock within the block (see the module); a
    `FolderInUseError` naming the holder's pid if another process holds it, a `FolderError` if
    the folder cannot be made or written. Reentrant within a process."""
    path = Path(folder)
    try:
        path.mkdir(parents=True, exist_ok=True)
        info = path.stat()
    except OSError as error:
        raise FolderError(f"cannot make the output folder {path}: {_reason(error)}") from None
    ident = (info.st_dev, info.st_ino)
    if ident in _held:
        fd, count = _held[ident]
        _held[ident] = (fd, count + 1)
    else:
        fd = _lock(path)  # creating the lock file also tries the folder (a read-only one fails)
        if not os.access(path, os.W_OK | os.X_OK):  # its lock file was there and writable
            os.close(fd)
            raise FolderError(
                f"cannot write in the output folder {path}: this user may not write in it"
            )
        _held[ident] = (fd, 1)
    try:
        yield path
    finally:
        fd, count = _held.pop(ident)
        if count > 1:
            _held[ident] = (fd, count - 1)
        else:
            os.close(fd)  # releases the lock


def forget_inherited() -> None:
    """In a forked child (a pool worker): close the lock descriptors inherited from the parent. A
    flock belongs to the open file, which a fork shares: a child keeping its copy would hold the
    parent's lock after the parent released it or ended. The parent's own copies keep it."""
    for fd, _ in _held.values():
        with contextlib.suppress(OSError):
            os.close(fd)
    _held.clear()


def _lock(folder: Path) -> int:
    lock = folder / LOCK_FILE
    allowed = f"allowed: a regular file (remove {lock} and run again)"
    try:  # O_NONBLOCK: opening a FIFO or a device found there must not wait
        fd = os.open(
            lock, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NONBLOCK, 0o644
        )
    except OSError as error:
        if error.errno == errno.ELOOP:  # O_NOFOLLOW met a symbolic link
            raise FolderError(f"cannot lock {lock}: it is a symbolic link; {allowed}") from None
        if error.errno == errno.EISDIR:
            raise FolderError(f"cannot lock {lock}: it is a folder; {allowed}") from None
        raise FolderError(f"cannot write in the output folder {folder}: {_reason(error)}") from None
    kind = os.fstat(fd).st_mode
    if not stat.S_ISREG(kind):  # a FIFO or a device: no pid can be written in it
        os.close(fd)
        raise FolderError(f"cannot lock {lock}: it is {_kind(kind)}, not a regular file; {allowed}")
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as error:
        holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
        os.close(fd)
        if error.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
            raise FolderError(f"cannot lock {lock}: {_reason(error)}") from None
        raise FolderInUseError(
            f"{folder} is being written by another sweep (pid {holder} holds {lock}); allowed: "
            "wait for it to end, or another output folder"
        ) from None
    try:  # the pid is a hint for a refused second sweep; writing it can fail on a full disk
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    except OSError as error:
        os.close(fd)  # releases the lock
        raise FolderError(
            f"cannot write the lock file {lock}: {_reason(error)}; allowed: a folder on a file "
            "system with room to write"
        ) from None
    return fd


def _kind(mode: int) -> str:
    """What a file that is not a regular one is, for a message."""
    for test, name in (
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISDIR, "a folder"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def _reason(error: OSError) -> str:
    return error.strerror or str(error)
