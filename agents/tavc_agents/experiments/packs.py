"""Per-trial results packed into one checksummed file per folder (`pack.jsonl`), and their loader.

A sweep saves each finished trial as its own `<key>.json` (`tavc_agents.experiments.sweep`), so a
study's folder can hold thousands of small files. `pack_folder` moves them into one `pack.jsonl`
beside them: one line per trial, sorted by key, each line

    {"key": ..., "schema": 1, "data": <the trial's record>, "sha256": ...}

where `sha256` is the SHA-256 of the line's text up to that field (closed with `}`), so a damaged
line is named by file, line and trial. The pack file's own SHA-256 goes into the folder's
`CHECKSUMS.sha256`, which catches lines added or removed. The pack is written atomically and read
back record by record before any loose file is deleted.

A sweep resuming in the folder finds a trial in its own loose file first, then in its pack line;
a damaged line is reported in one line and that trial runs again (saved as a loose file, which
the next packing moves in, replacing the damaged line). A study run with `--update-reference`
packs the trials it added to an already packed folder (`pack_new`).

`load_trials(folder)` reads every trial of a folder, packed or loose, in one call, and
`columns(records)` turns the records into columns (numpy arrays where the values are numbers).

    python -m tavc_agents.experiments.packs FOLDER...     # pack these folders of trials
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from tavc_agents.experiments.files import (
    MANIFEST,
    MANIFEST_MAX_BYTES,
    MIB,
    SCHEMA_VERSION,
    CorruptFileError,
    atomic_path,
    manifest_entry,
    read_bytes,
    read_record,
    read_text,
    write_text,
)
from tavc_agents.experiments.folders import hold_folder
from tavc_agents.experiments.runner import TrialResult
from tavc_env.safe_files import parse_json

PACK = "pack.jsonl"
PACK_MAX_BYTES = 1024 * MIB  # the largest committed pack is about 6 MiB
_LINE = re.compile(r'^(\{"key":.*),"sha256":"([0-9a-f]{64})"\}$', re.DOTALL)
_FAILED = ".failed.json"  # a sweep's record of a job that raised: not a result

R = TypeVar("R")


# -- one line ---------------------------------------------------------------------------------------
def _line(key: str, data: Mapping[str, Any]) -> str:
    """The pack line of trial `key` with record `data` (compact JSON, the record's key order)."""
    body = json.dumps({"key": key, "schema": SCHEMA_VERSION, "data": data}, separators=(",", ":"))
    return f'{body[:-1]},"sha256":"{hashlib.sha256(body.encode()).hexdigest()}"}}'


def _key_of(text: str) -> str | None:
    """The key a (possibly damaged) line names, if it can still be read."""
    found = re.match(r'^\{"key":("(?:[^"\\]|\\.)*")', text)
    if found is None:
        return None
    try:
        key = json.loads(found.group(1))
    except ValueError:
        return None
    return key if isinstance(key, str) else None


def _checked_line(text: str) -> tuple[str, dict[str, Any]] | str:
    """(key, data) of an intact line, or what is wrong with it."""
    found = _LINE.match(text)
    if found is None:
        return "is not a pack line (truncated or garbled)"
    body = found.group(1) + "}"
    if hashlib.sha256(body.encode()).hexdigest() != found.group(2):
        return "does not match its checksum: damaged or edited after it was packed"
    try:
        # NaN passes, as in the job records packed (their "undefined"); infinity does not
        parsed = parse_json(PACK, body, "pack line", nan=True)
    except CorruptFileError as error:  # a checksum that matches garbled or non-finite text
        return f"is not a valid record ({error})"
    if not isinstance(parsed, dict) or list(parsed) != ["key", "schema", "data"]:
        return "does not hold key, schema and data"
    if parsed["schema"] != SCHEMA_VERSION:
        return f"has schema {parsed['schema']!r}; allowed: {SCHEMA_VERSION} (this version's)"
    if not isinstance(parsed["key"], str) or not isinstance(parsed["data"], dict):
        return "does not hold a text key and a record"
    return parsed["key"], parsed["data"]


# -- one pack, read and checked ---------------------------------------------------------------------
@dataclass(frozen=True)
class _Index:
    """A pack read and checked: its lines by key (line number, text), what is wrong with each
    damaged line (by key; lines whose key cannot be read under None), and what is wrong with the
    file as a whole (lines added or removed; not listed in the manifest)."""

    path: Path
    lines: Mapping[str, tuple[int, str]]
    damaged: Mapping[str | None, str]
    problem: str | None

    def data(self, key: str) -> dict[str, Any] | None:
        """The record of `key` (a fresh copy), None if the pack has no intact line for it; a
        `CorruptFileError` naming the pack, line and trial if it is damaged or the pack is."""
        if self.problem is not None:
            raise CorruptFileError(f"{self.problem} (so {key!r} is not read from it)")
        if key in self.damaged:
            raise CorruptFileError(self.damaged[key])
        if key not in self.lines:
            return None
        checked = _checked_line(self.lines[key][1])
        assert not isinstance(checked, str)  # checked when the pack was read
        return checked[1]

    def where(self, key: str) -> str:
        return f"{self.path}, line {self.lines[key][0]} ({key})"


_CACHE: dict[Path, tuple[tuple[tuple[int, ...], ...], _Index]] = {}


def _stamp(path: Path) -> tuple[int, ...]:
    try:
        st = path.stat()
    except FileNotFoundError:
        return ()
    return (st.st_dev, st.st_ino, st.st_mtime_ns, st.st_size)


def _index(path: Path) -> _Index:
    """The pack at `path`, read and checked once per version of it and of its manifest (a sweep
    looks up thousands of trials in it)."""
    stamp = (_stamp(path), _stamp(path.parent / MANIFEST))
    cached = _CACHE.get(path)
    if cached is not None and cached[0] == stamp:
        return cached[1]
    index = _read_index(path)
    _CACHE[path] = (stamp, index)
    return index


def _read_index(path: Path) -> _Index:
    raw = read_bytes(path, PACK_MAX_BYTES, "trial pack")
    lines: dict[str, tuple[int, str]] = {}
    damaged: dict[str | None, str] = {}
    chunks = raw.split(b"\n")
    if chunks[-1] == b"":  # the newline that ends the last line
        chunks.pop()
    for number, chunk in enumerate(chunks, 1):
        text = chunk.decode("utf-8", errors="replace")
        checked = _checked_line(text)
        if isinstance(checked, str):
            key = _key_of(text)
            damaged.setdefault(key, f"{path}, line {number} ({key or 'key unreadable'}) {checked}")
        elif checked[0] in lines:
            damaged[checked[0]] = f"{path}, line {number} ({checked[0]}) repeats a key"
        else:
            lines[checked[0]] = (number, text)
    expected = manifest_entry(path)
    problem = None
    if expected is None:
        problem = f"{path} is not listed in {path.parent / MANIFEST}: not packed by this package"
    elif hashlib.sha256(raw).hexdigest() != expected and not damaged:
        problem = (
            f"{path} does not match its entry in {MANIFEST}: lines were added, removed or "
            "reordered after it was packed"
        )
    return _Index(path, lines, damaged, problem)


# -- what a sweep and the studies read ----------------------------------------------------------------
def find(folder: Path, key: str) -> tuple[dict[str, Any], str] | None:
    """The record of trial `key` packed in `folder` and where it is (file, line, key), None if
    the folder has no pack or the pack no line for it; a `CorruptFileError` naming the pack, line
    and trial if that line (or the pack as a whole) is damaged."""
    path = folder / PACK
    if not path.is_file():
        return None
    index = _index(path)
    data = index.data(key)
    return None if data is None else (data, index.where(key))


def parsed(
    found: tuple[dict[str, Any], str],
    parse: Callable[[dict[str, Any]], tuple[R, dict[str, Any] | None]],
    unit: str,
) -> tuple[R, dict[str, Any] | None]:
    """A packed record (`find`) as a job's result and stored settings, by the job kind's `parse`;
    a record it cannot take is a `CorruptFileError` naming the line."""
    data, where = found
    try:
        return parse(data)
    except (KeyError, TypeError) as error:
        raise CorruptFileError(f"{where} is not a saved {unit} ({error!r})") from None


def trial_from_data(data: dict[str, Any]) -> tuple[TrialResult, dict[str, Any] | None]:
    """A trial runner's result and its spec from its record (the `parse` of sweep trials)."""
    result = TrialResult.from_dict(data)
    return result, result.spec


def json_from_data(data: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """A JSON job's result and record from its saved record (the `parse` of `json_jobs`)."""
    result: dict[str, Any] = data["result"]
    return result, data.get("record")


def is_saved(path: str | Path) -> bool:
    """Whether the trial file `path` (`<folder>/<key>.json`) exists, or is packed in its folder."""
    path = Path(path)
    if path.exists():
        return True
    pack = path.parent / PACK
    return pack.is_file() and path.stem in _index(pack).lines


def read_saved(path: str | Path) -> dict[str, Any]:
    """The record saved as `path` (`<folder>/<key>.json`): the loose file if it exists, else its
    line in the folder's pack (checked either way; see `find`)."""
    path = Path(path)
    if path.exists():
        return read_record(path)
    found = find(path.parent, path.stem)
    if found is None:
        raise FileNotFoundError(
            f"{path} does not exist and is not packed in {path.parent / PACK}; allowed: a saved "
            "trial"
        )
    return found[0]


def load_trial(path: str | Path) -> TrialResult:
    """The trial runner's result saved as `path`, loose or packed (`read_saved`)."""
    data = read_saved(path)
    try:
        return TrialResult.from_dict(data)
    except TypeError as error:
        raise CorruptFileError(f"{path} is not a saved trial ({error})") from None


def saved_paths(pattern: str) -> list[str]:
    """The trial files matching the glob `pattern`, loose or packed (a packed trial as the path
    its loose file would have), sorted."""
    import fnmatch
    import glob

    found = set(glob.glob(pattern))
    for pack in glob.glob(os.path.join(os.path.dirname(pattern) or ".", PACK)):
        folder = os.path.dirname(pack)
        found |= {
            os.path.join(folder, f"{key}.json")
            for key in _index(Path(pack)).lines
            if fnmatch.fnmatch(os.path.join(folder, f"{key}.json"), pattern)
        }
    return sorted(found)


# -- the public loader --------------------------------------------------------------------------------
def _loose(folder: Path) -> list[Path]:
    """The loose result files of `folder` (a sweep's `<key>.json`; not its failure records)."""
    files = sorted(p for p in folder.glob("*.json") if not p.name.endswith(_FAILED))
    for path in files:
        if path.is_symlink() or not path.is_file():
            raise ValueError(
                f"{path} is not a regular file; allowed: result files saved by a sweep"
            )
    return files


def _all_records(folder: Path) -> dict[str, dict[str, Any]]:
    """Every trial of `folder` by key (its loose file over its pack line), sorted by key; a
    damaged pack or file is a `CorruptFileError` (nothing is left out silently)."""
    if not folder.is_dir():
        raise ValueError(f"folder = {str(folder)!r} is invalid; allowed: a folder of trials")
    records: dict[str, dict[str, Any]] = {}
    loose = {p.stem: p for p in _loose(folder)}
    pack = folder / PACK
    if pack.is_file():
        index = _index(pack)
        for key, problem in index.damaged.items():
            if key not in loose:
                raise CorruptFileError(problem)
        for key in index.lines:
            if key not in loose:
                data = index.data(key)
                assert data is not None
                records[key] = data
    for key, path in loose.items():
        records[key] = read_record(path, nan=True)  # job records keep NaN for "undefined"
    return {key: records[key] for key in sorted(records)}


def load_trials(folder: str | Path) -> list[dict[str, Any]]:
    """Every trial saved in `folder` (packed or loose), sorted by key: each its record with its
    key first, `{"key": ..., **record}` (a study's JSON job: `record` and `result`; a trial
    runner's trial: its `TrialResult` fields). Checked as a resume checks them; any damage is a
    `CorruptFileError` naming the file (and line)."""
    return [{"key": key, **data} for key, data in _all_records(Path(folder)).items()]


def columns(records: Sequence[Mapping[str, Any]]) -> dict[str, np.ndarray | list[Any]]:
    """The records as columns, named by their path of keys joined with dots
    (`result.fast_share`): a numpy array where every value is a number (float, with NaN for a
    record that lacks it or holds None) or every one a bool; otherwise a list (text, lists)."""
    flat = [_flatten(record) for record in records]
    names = list(dict.fromkeys(name for row in flat for name in row))
    return {name: _column([row.get(name) for row in flat]) for name in names}


def _flatten(data: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, value in data.items():
        if isinstance(value, Mapping) and value:
            out.update(_flatten(value, f"{prefix}{name}."))
        else:
            out[f"{prefix}{name}"] = value
    return out


def _column(values: list[Any]) -> np.ndarray | list[Any]:
    if values and all(isinstance(v, bool) for v in values):
        return np.array(values, dtype=bool)
    numbers = [v for v in values if v is not None]
    if numbers and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in numbers):
        if len(numbers) == len(values) and all(isinstance(v, int) for v in numbers):
            if all(-(2**63) <= v < 2**63 for v in numbers):
                return np.array(values, dtype=np.int64)
            return values
        return np.array([np.nan if v is None else float(v) for v in values])
    return values


# -- packing ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Packed:
    """What `pack_folder` did: the trials the pack holds, how many loose files it moved in (and
    deleted), and the pack's size in bytes."""

    pack: Path
    trials: int
    moved: int
    size: int

    def line(self) -> str:
        if not self.moved:
            return f"{self.pack}: {self.trials} trials; no loose file to pack"
        return (
            f"{self.pack}: {self.trials} trials ({self.moved} loose files packed and deleted), "
            f"{self.size:,} bytes"
        )


def pack_folder(folder: str | Path) -> Packed:
    """Move the loose trial files of `folder` into its `pack.jsonl` (made if there is none):
    write the pack atomically, list its digest in `CHECKSUMS.sha256`, read it back record by
    record, and only then delete the loose files. A loose file replaces the pack line of its key
    (a trial run again after its line was damaged). Damage anywhere is a `CorruptFileError`
    naming it, before anything is written."""
    folder = Path(folder)
    if not folder.is_dir():  # checked before the lock, which would make the folder
        raise ValueError(f"folder = {str(folder)!r} is invalid; allowed: a folder of trials")
    with hold_folder(folder):  # no sweep writes the folder while its files move
        return _pack_held(folder)


def _pack_held(folder: Path) -> Packed:
    records = _all_records(folder)  # checks the folder, the pack and every loose file first
    loose = _loose(folder)
    pack = folder / PACK
    if not loose:
        return Packed(pack, len(records), 0, pack.stat().st_size if pack.is_file() else 0)
    old = _index(pack).lines if pack.is_file() else {}
    moved = {p.stem for p in loose}
    # Lines already packed are kept as they are; only the loose records are written anew.
    lines = [old[k][1] if k in old and k not in moved else _line(k, v) for k, v in records.items()]
    with atomic_path(pack) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    _write_manifest(folder, pack)
    _verify(pack, records)
    for path in loose:
        path.unlink()
    _write_manifest(folder, pack)  # without the entries of the files just deleted
    return Packed(pack, len(records), len(loose), pack.stat().st_size)


def _verify(pack: Path, records: Mapping[str, Mapping[str, Any]]) -> None:
    """Read the written pack back and compare every record with what was packed (as JSON text,
    which also compares NaNs), before any loose file goes."""
    _CACHE.pop(pack, None)
    index = _index(pack)
    if index.problem is not None or index.damaged or list(index.lines) != list(records):
        raise CorruptFileError(f"{pack} did not read back as written; no loose file was deleted")
    for key, data in records.items():
        if json.dumps(index.data(key)) != json.dumps(data):
            raise CorruptFileError(
                f"{index.where(key)} did not read back as written; no loose file was deleted"
            )


def _write_manifest(folder: Path, pack: Path) -> None:
    """Set the pack's entry in the folder's manifest, keeping the entries of files that exist."""
    manifest = folder / MANIFEST
    entries: dict[str, str] = {}
    if manifest.exists():
        for line in read_text(manifest, MANIFEST_MAX_BYTES, "checksum manifest").splitlines():
            digest, _, name = line.partition("  ")
            if name and (folder / name).exists():
                entries[name] = digest
    entries[pack.name] = hashlib.sha256(read_bytes(pack, PACK_MAX_BYTES, "trial pack")).hexdigest()
    write_text(manifest, "".join(f"{entries[n]}  {n}\n" for n in sorted(entries)))


def pack_new(root: str | Path) -> list[Packed]:
    """Pack the loose files of every already packed folder under `root` (what a study run with
    `--update-reference` added to its committed, packed results)."""
    done = []
    for pack in sorted(Path(root).rglob(PACK)):
        if _loose(pack.parent):
            done.append(pack_folder(pack.parent))
    return done


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m tavc_agents.experiments.packs FOLDER...`: pack each folder, one line each."""
    folders = list(sys.argv[1:] if argv is None else argv)
    if not folders or any(f.startswith("-") for f in folders):
        print("usage: python -m tavc_agents.experiments.packs FOLDER...", file=sys.stderr)
        return 2
    for folder in folders:
        try:
            print(pack_folder(folder).line())
        except ValueError as error:  # CorruptFileError included
            print(f"{folder}: not packed: {error}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
