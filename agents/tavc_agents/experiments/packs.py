"""Per-trial results packed into one checksummed file per folder (`pack.jsonl`), and their loader.

A sweep saves each finished trial as its own `<key>.json` (`tavc_agents.experiments.sweep`), so a
study's folder can hold thousands of small files. `pack_folder` moves them into one `pack.jsonl`
beside them: one line per trial, sorted by key, each line

    {"key": ..., "schema": 1, "data": <the trial's record>, "sha256": ...}

where `sha256` is the SHA-256 of the line's text up to that field (closed with `}`), so a damaged
line is named by file, line and trial. The pack file's own SHA-256 goes into the folder's
`CHECKSUMS.sha256`, which catches lines added, removed or edited (with their own checksum
recomputed): a pack that does not match it is not used at all, whatever else is wrong with it.

Packing is safe to stop at any moment (a kill, a power cut, a full disk): at every step the folder
reads as it did before or as it will after, and the next packing finishes the job
(`docs/reliability.md` lists the steps). The new pack is written under a temporary name, then as
`pack.jsonl.new`, whose digest the manifest lists as pending (`pack.jsonl.new` beside the current
`pack.jsonl`) before the new pack is renamed over the old; a reader accepts `pack.jsonl` matching
either entry. The pack is read back record by record before any loose file is deleted.

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
    RECORD_MAX_BYTES,
    SCHEMA_VERSION,
    CorruptFileError,
    atomic_path,
    read_bytes,
    read_record,
    read_text,
    write_text,
)
from tavc_agents.experiments.folders import hold_folder
from tavc_agents.experiments.trial_result import TrialResult
from tavc_env.safe_files import kind_of, parse_json, sync_folder

PACK = "pack.jsonl"
PACK_MAX_BYTES = 1024 * MIB  # the largest committed pack is about 6 MiB
LINE_MAX_BYTES = RECORD_MAX_BYTES  # one trial's line: as large as its loose file may be
PENDING = PACK + ".new"  # the new pack, before it is renamed over the old (see the module)
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


def _manifest_lines(folder: Path) -> list[tuple[str, str]]:
    """The (name, digest) entries of `folder`'s manifest, in order (none if it has none)."""
    manifest = folder / MANIFEST
    if not os.path.lexists(manifest):
        return []
    text = read_text(manifest, MANIFEST_MAX_BYTES, "checksum manifest")
    entries = []
    for line in text.splitlines():
        digest, _, name = line.partition("  ")
        if name:
            entries.append((name, digest))
    return entries


def _pack_entries(path: Path) -> set[str]:
    """The digests the manifest vouches for `path` with: its own entry, and the pending new
    pack's while a packing is under way or was stopped (see the module)."""
    try:
        entries = _manifest_lines(path.parent)
    except CorruptFileError as error:
        raise CorruptFileError(f"{path} cannot be checked: {error}") from None
    return {digest for name, digest in entries if name in (path.name, PENDING)}


def _read_index(path: Path) -> _Index:
    raw = read_bytes(path, PACK_MAX_BYTES, "trial pack")
    lines: dict[str, tuple[int, str]] = {}
    damaged: dict[str | None, str] = {}
    chunks = raw.split(b"\n")
    if chunks[-1] == b"":  # the newline that ends the last line
        chunks.pop()
    for number, chunk in enumerate(chunks, 1):
        if len(chunk) > LINE_MAX_BYTES:  # refused before any matching or hashing of it
            key = _key_of(chunk[:4096].decode("utf-8", errors="replace"))
            damaged.setdefault(
                key,
                f"{path}, line {number} ({key or 'key unreadable'}) holds {len(chunk)} bytes, "
                f"more than the {LINE_MAX_BYTES} allowed for one trial",
            )
            continue
        text = chunk.decode("utf-8", errors="replace")
        checked = _checked_line(text)
        if isinstance(checked, str):
            key = _key_of(text)
            damaged.setdefault(key, f"{path}, line {number} ({key or 'key unreadable'}) {checked}")
        elif checked[0] in lines:
            damaged[checked[0]] = f"{path}, line {number} ({checked[0]}) repeats a key"
        else:
            lines[checked[0]] = (number, text)
    expected = _pack_entries(path)
    problem = None
    if not expected:
        problem = f"{path} is not listed in {path.parent / MANIFEST}: not packed by this package"
    elif hashlib.sha256(raw).hexdigest() not in expected:
        # Checked whatever else is wrong: with a damaged line beside it, a removed line or an
        # edited one with its checksum recomputed would otherwise pass unseen.
        some = f" ({len(damaged)} of its lines damaged)" if damaged else ""
        problem = (
            f"{path} does not match its entry in {MANIFEST}{some}: lines were damaged, added, "
            "removed, reordered or edited after it was packed, so none of its lines is used"
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
    """The loose result files of `folder` (a sweep's `<key>.json`; not its failure records); a
    symbolic link to a regular file is one (git-annex, DVC and DataLad keep files as links)."""
    files = sorted(
        p for p in folder.glob("*.json") if not p.name.endswith(_FAILED) and not _leftover(p.name)
    )
    for path in files:
        if not path.is_file():
            try:
                mode = path.stat().st_mode
                what = f"is {'a symbolic link to ' if path.is_symlink() else ''}{kind_of(mode)}"
            except OSError:
                what = "is a symbolic link to nothing"
            raise ValueError(
                f"{path} {what}, not a regular file; allowed: result files saved by a sweep "
                "(regular files or links to them)"
            )
    return files


def _leftover(name: str) -> bool:
    """Whether `name` is a temporary file a writer stopped part way left (`atomic_path`'s)."""
    return name.startswith(".") and ".tmp" in name


def _all_records(folder: Path, packing: bool = False) -> dict[str, dict[str, Any]]:
    """Every trial of `folder` by key (its loose file over its pack line), sorted by key; a
    damaged pack or file is a `CorruptFileError` (nothing is left out silently). When `packing`,
    a pack that does not match its manifest entry is superseded if every trial it names has a
    loose file (the sweep that named it ran them all again)."""
    if not folder.is_dir():
        raise ValueError(f"folder = {str(folder)!r} is invalid; allowed: a folder of trials")
    records: dict[str, dict[str, Any]] = {}
    loose = {p.stem: p for p in _loose(folder)}
    pack = folder / PACK
    if pack.is_file():
        index = _index(pack)
        superseded = (
            packing
            and index.problem is not None
            and all(key in loose for key in [*index.lines, *index.damaged])
        )
        if index.problem is not None and not superseded:
            raise CorruptFileError(index.problem)
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


class PackError(ValueError):
    """Packing stopped by the file system (a full disk, a folder turned read-only): one line
    naming the folder and the cause; the folder still reads as before (see the module)."""


def pack_folder(folder: str | Path) -> Packed:
    """Move the loose trial files of `folder` into its `pack.jsonl` (made if there is none):
    write the pack atomically, list its digest in `CHECKSUMS.sha256`, read it back record by
    record, and only then delete the loose files. A loose file replaces the pack line of its key
    (a trial run again after its line was damaged). Damage anywhere is a `CorruptFileError`
    naming it, before anything is written; a file system error (a full disk) is a `PackError`
    in one line. Stopped at any moment, it leaves every trial readable (see the module), and the
    next packing finishes the job."""
    if os.fspath(folder) == "":
        raise ValueError("folder = '' is invalid: an empty name; allowed: a folder of trials")
    folder = Path(folder)
    if not folder.is_dir():  # checked before the lock, which would make the folder
        raise ValueError(f"folder = {str(folder)!r} is invalid; allowed: a folder of trials")
    try:
        with hold_folder(folder):  # no sweep writes the folder while its files move
            return _pack_held(folder)
    except OSError as error:
        where = f" ({error.filename})" if error.filename else ""
        raise PackError(
            f"{folder} was not packed: {error.strerror or error}{where}; every trial still reads "
            "from its loose file or the pack, and packing again finishes the job"
        ) from None


def _pack_held(folder: Path) -> Packed:
    pack = folder / PACK
    _finish_stopped(folder, pack)
    records = _all_records(folder, packing=True)  # checks the folder, pack and loose files first
    loose = _loose(folder)
    if not loose:
        return Packed(pack, len(records), 0, pack.stat().st_size if pack.is_file() else 0)
    index = _index(pack) if pack.is_file() else None
    old = index.lines if index is not None and index.problem is None else {}
    moved = {p.stem for p in loose}
    # Lines already packed are kept as they are; only the loose records are written anew.
    lines = [old[k][1] if k in old and k not in moved else _line(k, v) for k, v in records.items()]
    raw = ("\n".join(lines) + "\n").encode()
    new = folder / PENDING
    # 1. the new pack, complete and on disk, under its own name (a stop leaves a temporary file,
    #    which the next packing removes)
    with atomic_path(new) as tmp:
        tmp.write_bytes(raw)
    # 2. the manifest vouches for it as pending, beside the current pack's entry
    _write_manifest(folder, {PENDING: hashlib.sha256(raw).hexdigest()})
    # 3. the new pack replaces the old: pack.jsonl matches the pending entry
    os.replace(new, pack)
    sync_folder(folder)
    # 4. the manifest lists it as the pack (the pending entry goes)
    _write_manifest(folder, {PACK: hashlib.sha256(raw).hexdigest()})
    _verify(pack, records)
    # 5. the loose files go, each now in the pack (a loose file over its line until it goes)
    for path in loose:
        path.unlink()
    sync_folder(folder)
    _write_manifest(folder, {})  # without the entries of the files just deleted
    return Packed(pack, len(records), len(loose), pack.stat().st_size)


def _finish_stopped(folder: Path, pack: Path) -> None:
    """Clear what a packing stopped part way left: its temporary files and a pending pack that
    was not renamed yet (its loose files are all still there); a pack already renamed over the
    old one has its entry set by `_write_manifest` (step 4 again)."""
    for path in folder.iterdir():  # the lock keeps every writer out: none of them is in use
        if _leftover(path.name) and path.is_file() and not path.is_symlink():
            path.unlink()
    if os.path.lexists(folder / PENDING):
        (folder / PENDING).unlink()
    entries = dict(_manifest_lines(folder))
    if PENDING in entries:
        if (
            pack.is_file()
            and hashlib.sha256(read_bytes(pack, PACK_MAX_BYTES, "trial pack")).hexdigest()
            == entries[PENDING]
        ):
            _write_manifest(folder, {PACK: entries[PENDING]})  # stopped after step 3
        else:
            _write_manifest(folder, {})  # stopped before step 3: the old pack stands
    _CACHE.pop(pack, None)


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


def _write_manifest(folder: Path, changed: Mapping[str, str]) -> None:
    """Set the `changed` entries (name: digest) of the folder's manifest, keeping those of files
    that exist; the pending entry is kept only if `changed` sets it, and setting the pack's
    entry drops it."""
    entries: dict[str, str] = {}
    for name, digest in _manifest_lines(folder):
        if name != PENDING and os.path.lexists(folder / name):
            entries[name] = digest
    entries.update(changed)
    write_text(folder / MANIFEST, "".join(f"{entries[n]}  {n}\n" for n in sorted(entries)))


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
        except ValueError as error:  # CorruptFileError and PackError included
            print(f"{folder}: not packed: {error}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(
                f"{folder}: packing interrupted; every trial still reads, and packing again "
                "finishes the job",
                file=sys.stderr,
            )
            return 130
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
