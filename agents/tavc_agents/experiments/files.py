"""Writing and reading result files safely.

A result is written to a temporary file with a unique name in the same folder, flushed to disk,
and renamed over its destination, so a reader (or a resumed sweep) sees the old file or the new
one, never half of one; concurrent writers never share a temporary file. Nothing that is not a
regular file (a symlink, a FIFO, a device node, a folder) is ever replaced: that is refused with
a ValueError naming the path and what it is.

Stored records carry a schema version and a SHA-256 checksum of their content, checked on load
(older records without one must be listed in a `CHECKSUMS.sha256` manifest beside them): a
truncated, garbled, too deeply nested or hand-edited file is reported in one line naming the file
and what is wrong (`CorruptFileError`), never used silently. Records are read through the safe
readers of `tavc_env.safe_files` (re-exported here): only a regular file of a bounded size, opened
without following a link or blocking, whose numbers are all finite; the checksums protect against
accidental damage, not a deliberate edit (anyone can recompute one).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tavc_env.safe_files import (
    MIB,
    CorruptFileError,
    atomic_path,
    check_writable,
    first_not_finite,
    kind_of,
    parse_json,
    read_bytes,
    read_json,
    read_text,
)

__all__ = [
    "MANIFEST",
    "MANIFEST_MAX_BYTES",
    "MIB",
    "RECORD_MAX_BYTES",
    "REPORT_MAX_BYTES",
    "SCHEMA_VERSION",
    "CorruptFileError",
    "atomic_path",
    "check_writable",
    "kind_of",
    "manifest_entry",
    "read_bytes",
    "read_csv",
    "read_json",
    "read_record",
    "read_report",
    "read_text",
    "write_manifest",
    "write_record",
    "write_text",
]

SCHEMA_VERSION = 1
# Vouches for records saved before they carried their own checksum; a record with neither is
# refused (it may be a hand edit that deleted the checksum).
MANIFEST = "CHECKSUMS.sha256"
# Size bounds of what is read back: far above anything saved (the largest committed trial record
# is 0.4 MiB, the largest report well under 1 MiB), far below what would exhaust memory.
RECORD_MAX_BYTES = 64 * MIB
MANIFEST_MAX_BYTES = 16 * MIB
REPORT_MAX_BYTES = 64 * MIB


def write_text(path: str | Path, text: str) -> Path:
    """Write `text` (UTF-8) to `path` atomically and safely (see the module)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def _digest(data: Mapping[str, Any]) -> str:
    canonical = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(canonical.encode()).hexdigest()


def write_record(path: str | Path, data: Mapping[str, Any], nan: bool = False) -> Path:
    """Write `data` as JSON with `schema` and `checksum` fields added (atomically). Its numbers
    must be finite (NaN is allowed with `nan`, for records that use it for "undefined"), as
    `read_record` checks them: a ValueError naming the path and the value otherwise."""
    body = {k: v for k, v in data.items() if k not in ("schema", "checksum")}
    where = first_not_finite(body, nan)
    if where is not None:
        raise ValueError(
            f"{path}: the value at {where} is not a finite number; allowed: finite numbers "
            f"{'or NaN ' if nan else ''}(a record is refused on load otherwise)"
        )
    body["schema"] = SCHEMA_VERSION
    body["checksum"] = _digest(body)
    return write_text(path, json.dumps(body))


def read_record(
    path: str | Path, nan: bool = False, limit: int = RECORD_MAX_BYTES
) -> dict[str, Any]:
    """The JSON record at `path`, checked: a regular file of at most `limit` bytes whose numbers
    are finite (NaN allowed with `nan`), its checksum and schema, or, for a record saved before
    records carried a checksum, its entry in the `CHECKSUMS.sha256` beside it (a record with
    neither is refused). A `CorruptFileError` names the file and what is wrong, in one line."""
    path = Path(path)
    raw = read_bytes(path, limit, "saved record")
    data = parse_json(path, raw, "saved record", nan)
    try:
        return _checked(path, raw, data)
    except RecursionError:  # re-encoding for the checksum recurses as decoding did
        raise CorruptFileError(
            f"{path} is nested deeper than the interpreter's recursion limit "
            f"({sys.getrecursionlimit()}) allows: not a saved record; allowed: a record saved by "
            "this package"
        ) from None


def _checked(path: Path, raw: bytes, data: Any) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise CorruptFileError(f"{path} holds {type(data).__name__}, not a JSON object")
    if "checksum" in data:
        stored = data.pop("checksum")
        if _digest(data) != stored:
            raise CorruptFileError(
                f"{path} does not match its checksum: it was edited or damaged after it was saved"
            )
        schema = data.pop("schema", None)
        if schema != SCHEMA_VERSION:
            raise CorruptFileError(
                f"{path} has schema {schema!r}; allowed: {SCHEMA_VERSION} (this version's)"
            )
        return data
    # Without a checksum only a manifest can tell an older record from one edited by hand (with
    # its checksum deleted): nothing else vouches for it.
    manifest = path.parent / MANIFEST
    expected = manifest_entry(path)
    if expected is None:
        where = (
            f"is not listed in {manifest}"
            if os.path.lexists(manifest)
            else f"there is no {manifest}"
        )
        raise CorruptFileError(
            f"{path} has no checksum and {where}: it was edited or not saved by this package; "
            f"allowed: a record with its checksum, or an older one listed in {MANIFEST} beside it"
        )
    if hashlib.sha256(raw).hexdigest() != expected:
        raise CorruptFileError(
            f"{path} does not match its entry in {MANIFEST}: it was edited or damaged after it "
            "was saved"
        )
    return data


def manifest_entry(path: Path) -> str | None:
    """The SHA-256 of `path` listed in its folder's manifest, if there is one (a garbled
    manifest raises `CorruptFileError` naming it)."""
    manifest = path.parent / MANIFEST
    if not os.path.lexists(manifest):
        return None
    try:
        text = read_text(manifest, MANIFEST_MAX_BYTES, "checksum manifest")
    except CorruptFileError as error:
        raise CorruptFileError(f"{path} cannot be checked: {error}") from None
    for line in text.splitlines():
        digest, _, name = line.partition("  ")
        if name == path.name:
            return digest
    return None


def write_manifest(folder: str | Path, pattern: str = "*.json") -> Path:
    """List the SHA-256 of every file matching `pattern` in `folder` in `CHECKSUMS.sha256`
    (the format `sha256sum -c` reads), for records saved before they carried a checksum."""
    folder = Path(folder)
    lines = [
        f"{hashlib.sha256(read_bytes(p, RECORD_MAX_BYTES, 'saved record')).hexdigest()}  {p.name}"
        for p in sorted(folder.glob(pattern))
    ]
    return write_text(folder / MANIFEST, "\n".join(lines) + "\n")


def read_report(path: str | Path) -> Any:
    """A JSON report (or any JSON result file this package writes without a checksum, such as a
    study's plan), read safely: a regular file of at most `REPORT_MAX_BYTES`, finite numbers
    (reports write undefined values as null); a `CorruptFileError` naming it otherwise."""
    return read_json(path, REPORT_MAX_BYTES, "JSON report")


def read_csv(path: str | Path) -> csv.DictReader[str]:
    """A `csv.DictReader` over the CSV table at `path` (a report's, `references.csv`, ...), read
    safely: a regular file of at most `REPORT_MAX_BYTES` of UTF-8 text."""
    text = read_text(path, REPORT_MAX_BYTES, "CSV table")
    return csv.DictReader(io.StringIO(text, newline=""))
