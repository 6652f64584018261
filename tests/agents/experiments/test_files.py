"""Safe files: nothing but a regular file is ever replaced, writes are atomic with unique
temporary names, and stored records are checked on load."""

from __future__ import annotations

import hashlib
import json
import os
import sys
import threading
from pathlib import Path

import pytest

from tavc_agents.analysis.reports import write_csv
from tavc_agents.experiments.files import (
    CorruptFileError,
    atomic_path,
    read_record,
    write_manifest,
    write_record,
    write_text,
)


def test_a_symlink_fifo_or_device_at_the_path_is_refused_and_left_alone(tmp_path: Path) -> None:
    target = tmp_path / "precious.txt"
    target.write_text("keep me")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    with pytest.raises(ValueError, match="is a symbolic link; refusing to replace it"):
        write_text(link, "x")
    assert link.is_symlink() and target.read_text() == "keep me"
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="is a FIFO"):
        write_csv(fifo, [{"a": 1}])
    with pytest.raises(ValueError, match="is a character device"):
        write_text("/dev/full", "x")
    with pytest.raises(ValueError, match="is a folder"):
        write_text(tmp_path, "x")
    with pytest.raises(ValueError, match="does not exist"):
        write_text(tmp_path / "missing" / "x.json", "x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "pipe.csv", "precious.txt"]


def test_a_regular_file_is_replaced_atomically(tmp_path: Path) -> None:
    path = tmp_path / "r.json"
    path.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(path) as tmp:
        tmp.write_text("half")
        raise RuntimeError("the writer died")
    assert path.read_text() == "old" and os.listdir(tmp_path) == ["r.json"]
    write_text(path, "new")
    assert path.read_text() == "new" and os.listdir(tmp_path) == ["r.json"]


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_written_files_honour_the_umask(tmp_path: Path, umask: int) -> None:
    """A file the package writes (a record, a report, a pack) gets mode 0o666 less the umask, as
    `open` gives a new file; it was 0o600 whatever the umask (`mkstemp`), so a colleague sharing
    the folder could not read a trial.json."""
    previous = os.umask(umask)
    try:
        write_csv(tmp_path / "table.csv", [{"a": 1}])
        written = [
            write_text(tmp_path / "report.md", "x"),
            write_record(tmp_path / "trial.json", {"a": 1}),
            tmp_path / "table.csv",
        ]
        (tmp_path / "old.json").write_text("old")
        written.append(write_text(tmp_path / "old.json", "new"))  # replacing a file too
    finally:
        os.umask(previous)
    for path in written:
        assert oct(Path(path).stat().st_mode & 0o777) == oct(0o666 & ~umask), path


def test_concurrent_writers_do_not_share_a_temporary_file(tmp_path: Path) -> None:
    path = tmp_path / "shared.json"
    errors: list[BaseException] = []

    def writer(k: int) -> None:
        try:
            for _ in range(50):
                write_text(path, json.dumps({"writer": k, "pad": "x" * 10_000}))
        except BaseException as error:  # pragma: no cover - the failure being tested for
            errors.append(error)

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert json.loads(path.read_text())["writer"] in range(4)  # whole, from one writer
    assert os.listdir(tmp_path) == ["shared.json"]


def test_records_carry_a_checksum_and_schema_checked_on_load(tmp_path: Path) -> None:
    path = write_record(tmp_path / "r.json", {"x": [1, 2.5], "y": "z"})
    assert read_record(path) == {"x": [1, 2.5], "y": "z"}
    data = json.loads(path.read_text())
    assert data["schema"] == 1 and len(data["checksum"]) == 64
    data["x"][0] = 2
    path.write_text(json.dumps(data))
    with pytest.raises(CorruptFileError, match=r"r\.json does not match its checksum"):
        read_record(path)
    raw = {"x": 1, "schema": 0}  # a record of another schema, with a valid checksum
    raw["checksum"] = hashlib.sha256(
        json.dumps(raw, sort_keys=True, separators=(",", ":")).encode()
    ).hexdigest()
    path.write_text(json.dumps(raw))
    with pytest.raises(CorruptFileError, match="has schema 0; allowed: 1"):
        read_record(path)
    path.write_text('{"x": ')
    with pytest.raises(CorruptFileError, match=r"r\.json is not valid JSON"):
        read_record(path)
    path.write_text("[1, 2]")
    with pytest.raises(CorruptFileError, match="holds list, not a JSON object"):
        read_record(path)


def test_old_records_are_checked_against_their_folders_manifest(tmp_path: Path) -> None:
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"a": 1}))  # saved before records carried a checksum
    # Nothing vouches for it: it could be a hand edit that deleted the checksum.
    with pytest.raises(
        CorruptFileError, match=r"old\.json has no checksum and there is no .*CHECKSUMS\.sha256"
    ):
        read_record(old)
    write_manifest(tmp_path)
    assert read_record(old) == {"a": 1}
    old.write_text(json.dumps({"a": 2}))
    with pytest.raises(CorruptFileError, match=r"does not match its entry in CHECKSUMS\.sha256"):
        read_record(old)
    other = tmp_path / "other.json"  # added after the manifest was written
    other.write_text(json.dumps({"b": 1}))
    with pytest.raises(
        CorruptFileError, match=r"other\.json has no checksum and is not listed in .*CHECKSUMS"
    ):
        read_record(other)
    (tmp_path / "CHECKSUMS.sha256").write_bytes(b"\xff\xfe garbled")
    with pytest.raises(CorruptFileError, match=r"old\.json cannot be checked: .* not UTF-8"):
        read_record(old)


@pytest.mark.parametrize("checksum", [False, True])
def test_nesting_near_or_past_the_recursion_limit_is_refused_naming_the_file(
    tmp_path: Path, checksum: bool
) -> None:
    """Decoding and re-encoding (for the checksum) both recurse per level: at no depth does a
    RecursionError escape instead of a `CorruptFileError` naming the file."""
    path = tmp_path / "deep.json"
    limit = sys.getrecursionlimit()
    for depth in [*range(limit - 100, limit + 5), 10 * limit]:
        tail = ', "checksum": "' + "0" * 64 + '"' if checksum else ""
        path.write_text('{"x": ' + "[" * depth + "]" * depth + tail + "}")
        with pytest.raises(CorruptFileError) as caught:
            read_record(path)
        assert str(path) in str(caught.value) and "\n" not in str(caught.value)
