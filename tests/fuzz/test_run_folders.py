"""Fuzzing damaged run folders (issue 28, item 6): a small real run folder (three short trials in
`trials/`, `provenance.json` beside them, written by `run_recorded` as every study writes its
folder) has random trial slots and its provenance deleted or replaced by any damage of
`tests.damage` (a folder, links, /dev/zero, a FIFO, garbled, truncated, `[]`, NaN or infinity
under a valid checksum, a 5000-digit integer, a file over its size bound); then the run is
resumed under `no_hang`. Every outcome must be one of:

* a provenance that is not a regular file: refused before any trial, in one line naming it, the
  trial slots left as they were;
* otherwise the run finishes: each damaged trial named in one line, moved aside (never deleted)
  and run again to the undisturbed result; each deleted one run; each intact one resumed
  byte for byte; a damaged provenance file named in one line and replaced.

The tally of outcomes is printed at the end of the module (`-s` shows it).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import tempfile
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tavc_agents.experiments.files import RECORD_MAX_BYTES, CorruptFileError
from tavc_agents.experiments.provenance import (
    PROVENANCE_FILE,
    PROVENANCE_MAX_BYTES,
    load_provenance,
)
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import run_recorded
from tavc_agents.experiments.sweep import TRIALS, TrialSpec
from tests.damage import DAMAGES, NOT_FILES, no_hang, plant
from tests.fuzz.strategies import fuzz_settings

SPECS = [
    TrialSpec(
        key=f"k{k}",
        allocator=("random", "softmax_tavc")[k % 2],
        seed=200 + k,
        convergence_s=10.0,
        measured_s=10.0,
        snapshot_every_s=10.0,
    )
    for k in range(3)
]
SETTINGS = {"trials": len(SPECS)}
TRIAL_FATES = ("keep", "keep", "keep", "delete", *DAMAGES)
PROVENANCE_FATES = ("keep", "keep", "delete", *DAMAGES)
TALLY: Counter[str] = Counter()


@pytest.fixture(scope="module", autouse=True)
def tally() -> Iterator[None]:
    yield
    if TALLY:
        lines = [f"  {name}: {count}" for name, count in sorted(TALLY.items())]
        print("\ndamaged run folders, outcomes:\n" + "\n".join(lines))


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("clean_run_folder")
    with contextlib.redirect_stderr(io.StringIO()):
        run_recorded(SPECS, TRIALS, folder / "trials", folder, SETTINGS, workers=1)
    return folder


def _canonical(result: TrialResult) -> str:
    data = result.to_dict()
    data.pop("wall_s")
    return json.dumps(data, sort_keys=True)


def _run(folder: Path) -> tuple[dict[str, TrialResult] | None, str, BaseException | None]:
    err = io.StringIO()
    try:
        with no_hang(120), contextlib.redirect_stderr(err):
            results, _ = run_recorded(
                SPECS, TRIALS, folder / "trials", folder, SETTINGS, workers=1, progress_bar=False
            )
    except CorruptFileError as error:
        return None, err.getvalue(), error
    return results, err.getvalue(), None


@fuzz_settings(70)
@given(
    trial_fates=st.lists(st.sampled_from(TRIAL_FATES), min_size=len(SPECS), max_size=len(SPECS)),
    provenance_fate=st.sampled_from(PROVENANCE_FATES),
)
def test_a_damaged_run_folder_resumes_or_is_refused_in_one_line(
    clean: Path, trial_fates: list[str], provenance_fate: str
) -> None:
    with tempfile.TemporaryDirectory(prefix="tavc-fuzz-run-") as name:
        folder = Path(name) / "run"
        shutil.copytree(clean, folder)
        trials = folder / "trials"
        for spec, fate in zip(SPECS, trial_fates):
            slot = trials / f"{spec.key}.json"
            if fate == "delete":
                slot.unlink()
            elif fate != "keep":
                plant(slot, fate, (clean / "trials" / slot.name).read_bytes(), RECORD_MAX_BYTES)
        provenance = folder / PROVENANCE_FILE
        if provenance_fate == "delete":
            provenance.unlink()
        elif provenance_fate != "keep":
            raw = (clean / PROVENANCE_FILE).read_bytes()
            plant(provenance, provenance_fate, raw, PROVENANCE_MAX_BYTES)
        before = sorted(os.listdir(trials))

        results, err, error = _run(folder)

        TALLY["cases"] += 1
        TALLY["trial slots checked"] += len(SPECS)
        if provenance_fate in NOT_FILES:  # cannot be replaced without deleting it: refused
            assert error is not None, f"a provenance that is {provenance_fate} was accepted"
            assert str(provenance) in str(error) and "\n" not in str(error)
            assert sorted(os.listdir(trials)) == before  # before any trial: nothing touched
            TALLY["provenance refused before any trial"] += 1
            return
        assert error is None, f"{error}"
        assert results is not None
        lines = err.strip().splitlines()
        if provenance_fate in DAMAGES:
            assert any(
                line.startswith(f"{provenance} ") and "replaced by this run's" in line
                for line in lines
            ), err
            TALLY["provenance named and replaced"] += 1
        else:
            TALLY[f"provenance {'read' if provenance_fate == 'keep' else 'missing'}"] += 1
        assert load_provenance(folder) is not None or provenance_fate == "delete"
        damaged = 0
        for spec, fate in zip(SPECS, trial_fates):
            slot = trials / f"{spec.key}.json"
            original = clean / "trials" / slot.name
            assert _canonical(results[spec.key]) == _canonical(TrialResult.load(original))
            assert _canonical(TrialResult.load(slot)) == _canonical(results[spec.key])
            if fate == "keep":
                assert slot.read_bytes() == original.read_bytes()  # resumed, not rerun
                TALLY["trials intact, resumed"] += 1
            elif fate == "delete":
                TALLY["trials missing, run"] += 1
            else:
                damaged += 1
                named = [line for line in lines if line.startswith(f"{slot} ")]
                assert len(named) == 1, err
                assert named[0].endswith(f"running trial {spec.key!r} again")
                aside = "not-a-file" if fate in NOT_FILES else "damaged"
                assert os.path.lexists(trials / f"{slot.name}.{aside}")  # kept, not deleted
                TALLY["trials damaged, named, moved aside and rerun"] += 1
        replaced = provenance_fate in DAMAGES
        assert len(lines) == damaged + replaced, err  # nothing else said, each in one line
