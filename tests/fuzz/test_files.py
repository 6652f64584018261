"""Fuzzing stored trial files: truncated, garbled, edited or replaced files, deleted files, stray
temporary files and sweeps interrupted (by Ctrl-C after a trial, or by a failing save). A file that
is not the one saved gives `CorruptFileError` (a ValueError) naming it; a resumed sweep runs those
trials again, keeps the others untouched, and ends with every trial on disk, whole, and equal to
an undisturbed run; no trial file is ever lost or left half-written."""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from unittest import mock

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tavc_agents.experiments.files import CorruptFileError
from tavc_agents.experiments.folders import LOCK_FILE
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.sweep import SaveError, SweepError, TrialSpec, run_sweep
from tests.fuzz.strategies import fuzz_settings

SPECS = [
    TrialSpec(
        key=f"trial{k}",
        allocator=("random", "softmax_tavc")[k % 2],
        seed=100 + k,
        convergence_s=60.0,
        measured_s=60.0,
        snapshot_every_s=60.0,
    )
    for k in range(4)
]
KEYS = [spec.key for spec in SPECS]


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """The files of an undisturbed sweep, by key."""
    folder = tmp_path_factory.mktemp("clean_sweep")
    run_sweep(SPECS, folder, workers=1)
    return {key: (folder / f"{key}.json").read_bytes() for key in KEYS}


@contextlib.contextmanager
def sweep_folder(clean: dict[str, bytes], keys: list[str]) -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix="tavc-fuzz-") as name:
        folder = Path(name)
        for key in keys:
            (folder / f"{key}.json").write_bytes(clean[key])
        yield folder


def _canonical(data: Any) -> str:
    return json.dumps(data, sort_keys=True, allow_nan=True)


def _same_trial(a: TrialResult, b: TrialResult) -> bool:
    da, db = a.to_dict(), b.to_dict()
    da.pop("wall_s")
    db.pop("wall_s")
    return _canonical(da) == _canonical(db)


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3)
    ),
    max_leaves=8,
)


@st.composite
def damage(draw: st.DrawFn, raw: bytes) -> bytes:
    """`raw` (a stored trial) truncated, garbled, edited (a field removed, replaced, nudged, or
    an element of a list changed, the checksum kept), replaced by other JSON, emptied or
    replaced by random bytes."""
    kind = draw(st.sampled_from(["truncate", "garble", "edit", "edit", "replace", "bytes"]))
    if kind == "truncate":
        return raw[: draw(st.integers(0, len(raw) - 1))]
    if kind == "garble":
        data = bytearray(raw)
        for _ in range(draw(st.integers(1, 6))):
            data[draw(st.integers(0, len(raw) - 1))] = draw(st.integers(0, 255))
        return bytes(data)
    if kind == "replace":
        return json.dumps(draw(JSON_VALUES)).encode()
    if kind == "bytes":
        return draw(st.binary(max_size=80))
    record = json.loads(raw)
    key = draw(st.sampled_from(sorted(k for k in record if k != "checksum")))
    value = record[key]
    how = draw(st.sampled_from(["remove", "replace", "nudge", "element"]))
    if how == "remove":
        del record[key]
    elif how == "nudge" and isinstance(value, (int, float)) and not isinstance(value, bool):
        record[key] = value + draw(st.sampled_from([1, -1, 1e-9, 0.5]))
    elif how == "element" and isinstance(value, list) and value:
        value[draw(st.integers(0, len(value) - 1))] = draw(JSON_VALUES)
    else:
        record[key] = draw(JSON_VALUES)
    return json.dumps(record).encode()


@fuzz_settings(60)
@given(data=st.data())
def test_a_damaged_trial_file_is_refused_naming_it(
    clean: dict[str, bytes], data: st.DataObject
) -> None:
    key = data.draw(st.sampled_from(KEYS), label="key")
    raw = data.draw(damage(clean[key]), label="damaged")
    with sweep_folder(clean, []) as folder:
        path = folder / f"{key}.json"
        path.write_bytes(raw)
        try:
            unchanged = _canonical(json.loads(raw)) == _canonical(json.loads(clean[key]))
        except ValueError:  # not JSON (or not UTF-8)
            unchanged = False
        if unchanged:  # the same content (say, other white space): still the saved trial
            loaded = TrialResult.load(path)
            original = folder / "original.json"
            original.write_bytes(clean[key])
            assert _same_trial(loaded, TrialResult.load(original))
            return
        with pytest.raises(CorruptFileError) as caught:
            TrialResult.load(path)
        assert isinstance(caught.value, ValueError)
        assert str(path) in str(caught.value)
        assert "\n" not in str(caught.value)  # one line


@fuzz_settings(20)
@given(
    fates=st.lists(
        st.sampled_from(["keep", "keep", "damage", "delete"]),
        min_size=len(KEYS),
        max_size=len(KEYS),
    ),
    strays=st.integers(0, 3),
    data=st.data(),
)
def test_a_resumed_sweep_reruns_damaged_trials_and_keeps_the_others(
    clean: dict[str, bytes], fates: list[str], strays: int, data: st.DataObject
) -> None:
    with sweep_folder(clean, KEYS) as folder:
        damaged = []
        for key, fate in zip(KEYS, fates):
            path = folder / f"{key}.json"
            if fate == "delete":
                path.unlink()
            elif fate == "damage":
                raw = data.draw(damage(clean[key]), label=f"{key} damaged")
                try:
                    if _canonical(json.loads(raw)) == _canonical(json.loads(clean[key])):
                        continue  # the same content: not damaged
                except ValueError:
                    pass
                path.write_bytes(raw)
                damaged.append(key)
        for k in range(strays):  # half-written temporary files left by a killed writer
            stray = folder / f".{KEYS[k]}.json.x{k}.tmp.json"
            stray.write_bytes(clean[KEYS[k]][: 10 * k])
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            results = run_sweep(SPECS, folder, workers=1)
        for key in damaged:
            assert f"{folder / key}.json" in err.getvalue()
            assert f"running trial {key!r} again" in err.getvalue()
        for key, fate in zip(KEYS, fates):
            path = folder / f"{key}.json"
            stored = TrialResult.load(path)
            original = folder / "original.json"
            original.write_bytes(clean[key])
            assert _same_trial(stored, TrialResult.load(original))
            assert _same_trial(results[key], stored)
            if fate == "keep":
                assert path.read_bytes() == clean[key]  # resumed, not rewritten


@fuzz_settings(20)
@given(
    stop_after=st.integers(1, len(KEYS) - 1), failing_save=st.integers(0, len(KEYS)), data=st.data()
)
def test_an_interrupted_sweep_leaves_only_whole_trial_files(
    clean: dict[str, bytes], stop_after: int, failing_save: int, data: st.DataObject
) -> None:
    """Ctrl-C after `stop_after` finished trials, or a save that fails at its rename (when
    `failing_save` < number of trials): every trial file on disk is whole; a rerun completes."""
    with sweep_folder(clean, []) as folder:
        done: list[str] = []

        def on_done(spec: TrialSpec, result: TrialResult, resumed: bool) -> None:
            done.append(spec.key)
            if len(done) == stop_after:
                raise KeyboardInterrupt

        renames = [0]
        real_replace = os.replace

        def replace(src: Any, dst: Any) -> None:
            if str(dst).endswith(".json") and not str(dst).endswith(".failed.json"):
                renames[0] += 1
                if renames[0] == failing_save + 1 and failing_save < len(KEYS):
                    raise OSError(28, "No space left on device (simulated)")
            real_replace(src, dst)

        with (
            mock.patch("tavc_agents.experiments.files.os.replace", replace),
            pytest.raises((KeyboardInterrupt, SweepError, SaveError)),  # a refused save stops it
        ):
            run_sweep(SPECS, folder, workers=1, on_done=on_done)
        for path in folder.iterdir():
            assert ".tmp" not in path.name, f"a temporary file was left: {path.name}"
            if path.name.endswith(".failed.json") or path.name == LOCK_FILE:
                continue
            TrialResult.load(path)  # whole (raises CorruptFileError otherwise)
        results = run_sweep(SPECS, folder, workers=1)
        for key in KEYS:
            original = folder / "original.json"
            original.write_bytes(clean[key])
            assert _same_trial(results[key], TrialResult.load(original))
            assert _same_trial(TrialResult.load(folder / f"{key}.json"), results[key])


def test_an_edited_file_without_its_checksum_is_refused(
    clean: dict[str, bytes], tmp_path: Path
) -> None:
    """A hand edit that also deletes `checksum` and `schema` is not taken for an older record:
    only a `CHECKSUMS.sha256` beside it could vouch for that; a resumed sweep runs it again."""
    record = json.loads(clean[KEYS[0]])
    del record["checksum"], record["schema"]
    record["delivery_time_s"] = [1.0, 2.0]
    path = tmp_path / f"{KEYS[0]}.json"
    path.write_text(json.dumps(record))
    with pytest.raises(CorruptFileError, match="has no checksum") as caught:
        TrialResult.load(path)
    assert str(path) in str(caught.value)
    assert "\n" not in str(caught.value)  # one line
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        results = run_sweep(SPECS[:1], tmp_path, workers=1)
    assert f"{path} has no checksum" in err.getvalue()
    assert f"running trial {KEYS[0]!r} again" in err.getvalue()
    original = tmp_path / "original.json"
    original.write_bytes(clean[KEYS[0]])
    assert _same_trial(results[KEYS[0]], TrialResult.load(original))
    assert _same_trial(TrialResult.load(path), results[KEYS[0]])


def test_a_deeply_nested_file_is_refused_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000)
    with pytest.raises(CorruptFileError, match="nested deeper than") as caught:
        TrialResult.load(path)
    assert str(path) in str(caught.value)
    assert "\n" not in str(caught.value)  # one line
