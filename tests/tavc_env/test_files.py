"""The safe readers (`tavc_env.safe_files`): only a regular file of a bounded size is read, without
following a link or blocking; anything else, and JSON that is garbled, not finite or holds an
integer too long to convert, is a `CorruptFileError` (a ValueError) naming the file in one line.
Every case runs under `no_hang`, so a reader that blocks fails instead of hanging the suite."""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

import pytest

from tavc_env.safe_files import CorruptFileError, first_not_finite, read_bytes, read_json, read_text
from tests.damage import DAMAGES, NOT_FILES, no_hang, plant

GOOD = json.dumps({"a": 1, "b": [0.5, 2]}).encode()
LIMIT = 4096


@pytest.fixture(autouse=True)
def guard() -> Iterator[None]:
    with no_hang(30):
        yield


def refused(path: Path, nan: bool = False) -> str:
    with pytest.raises(CorruptFileError) as caught:
        read_json(path, LIMIT, "test file", nan=nan)
    message = str(caught.value)
    assert isinstance(caught.value, ValueError)
    assert str(path) in message
    assert "\n" not in message  # one line
    return message


@pytest.mark.parametrize("how", [d for d in DAMAGES if d != "list"])  # JSON: the callers' to refuse
def test_every_damage_is_refused_naming_the_file(tmp_path: Path, how: str) -> None:
    path = tmp_path / "f.json"
    plant(path, how, GOOD, limit=LIMIT)
    message = refused(path)
    if how in NOT_FILES:
        kind = {
            "folder": "is a folder, not a regular file",
            "fifo": "is a FIFO, not a regular file",
            "dev_zero": "is a symbolic link to a character device, not a regular file",
        }.get(how, "is a symbolic link to ")
        assert kind in message


def test_a_good_file_reads(tmp_path: Path) -> None:
    path = tmp_path / "f.json"
    plant(path, "keep", GOOD)
    assert read_json(path, LIMIT) == {"a": 1, "b": [0.5, 2]}
    assert read_bytes(path, len(GOOD)) == GOOD  # exactly at the bound
    with pytest.raises(CorruptFileError, match=f"holds {len(GOOD)} bytes, more than the"):
        read_bytes(path, len(GOOD) - 1)


def test_a_missing_file_is_named(tmp_path: Path) -> None:
    assert "does not exist" in refused(tmp_path / "none.json")


def test_the_device_itself_and_its_link_are_refused_without_reading() -> None:
    with pytest.raises(CorruptFileError, match="/dev/zero is a character device"):
        read_bytes("/dev/zero", LIMIT)


def test_a_fifo_swapped_in_after_the_look_is_caught_by_fstat_without_blocking(
    tmp_path: Path,
) -> None:
    """The race: `lstat` saw a regular file, the open finds a FIFO with no writer. O_NONBLOCK
    makes the open return at once, and `fstat` of the descriptor refuses it."""
    path = tmp_path / "f.json"
    os.mkfifo(path)
    regular = os.stat_result((stat.S_IFREG | 0o644, 0, 0, 1, 0, 0, 10, 0, 0, 0))
    with (
        mock.patch.object(Path, "lstat", return_value=regular),
        pytest.raises(CorruptFileError, match=r"f\.json is a FIFO, not a regular file"),
    ):
        read_bytes(path, LIMIT)


def test_a_link_to_a_regular_file_is_read(tmp_path: Path) -> None:
    """git-annex, DVC and DataLad keep files as symbolic links into their stores: a link to a
    regular file is read through (it was refused, locking their users out)."""
    path = tmp_path / "f.json"
    plant(path, "link", GOOD)
    assert path.is_symlink()
    assert read_json(path, LIMIT) == {"a": 1, "b": [0.5, 2]}


@pytest.mark.parametrize("to", ["fifo", "folder", "device", "nowhere"])
def test_a_link_to_anything_but_a_regular_file_is_refused_naming_it(
    tmp_path: Path, to: str
) -> None:
    target = {"device": Path("/dev/zero"), "nowhere": tmp_path / "nowhere"}.get(to, tmp_path / to)
    if to == "fifo":
        os.mkfifo(target)
    elif to == "folder":
        target.mkdir()
    path = tmp_path / "f.json"
    path.symlink_to(target)
    expected = {
        "fifo": "is a symbolic link to a FIFO, not a regular file",
        "folder": "is a symbolic link to a folder, not a regular file",
        "device": "is a symbolic link to a character device, not a regular file",
        "nowhere": f"is a symbolic link to {str(target)!r}, which cannot be read",
    }[to]
    assert expected in refused(path)


def test_a_file_growing_past_its_bound_while_read_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "f.json"
    path.write_bytes(b"x" * 10)
    real_fstat = os.fstat

    def small(fd: int) -> os.stat_result:  # the size fstat saw before the file grew
        info = real_fstat(fd)
        return os.stat_result((info.st_mode, 0, 0, 1, 0, 0, 1, 0, 0, 0))

    with (
        mock.patch("tavc_env.safe_files.os.fstat", small),
        pytest.raises(CorruptFileError, match="grew past the 5 bytes allowed"),
    ):
        read_bytes(path, 5)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("NaN", "holds the value NaN (not a finite number)"),
        ('{"a": [1, -Infinity]}', "holds the value -Infinity"),
        ('{"a": {"b": 1e999}}', "not a finite number at .a.b"),
        ("[" * 100_000, "nested deeper than the recursion limit"),
        ("9" * 5000, "holds an integer too long to convert (Exceeds the limit"),
        ('{"a": ', "is not valid JSON"),
    ],
)
def test_json_must_be_whole_and_finite(tmp_path: Path, text: str, expected: str) -> None:
    path = tmp_path / "f.json"
    path.write_text(text)
    with pytest.raises(CorruptFileError) as caught:
        read_json(path, 10**6)
    assert expected in str(caught.value)
    assert str(path) in str(caught.value)
    assert "\n" not in str(caught.value)


def test_nan_is_allowed_only_when_asked_and_infinity_never(tmp_path: Path) -> None:
    path = tmp_path / "f.json"
    path.write_text('{"gap": NaN}')
    assert first_not_finite(read_json(path, LIMIT, nan=True)) == ".gap"
    path.write_text('{"gap": Infinity}')
    refused(path, nan=True)
    path.write_text('{"gap": 1e400}')
    refused(path, nan=True)


def test_text_must_be_utf8(tmp_path: Path) -> None:
    path = tmp_path / "f.txt"
    path.write_bytes(b"ok \xff")
    with pytest.raises(CorruptFileError, match=r"f\.txt is not UTF-8 text"):
        read_text(path, LIMIT)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads any file")
def test_an_unreadable_file_is_named(tmp_path: Path) -> None:
    path = tmp_path / "f.json"
    path.write_bytes(GOOD)
    path.chmod(0)
    assert "cannot be opened" in refused(path)
