"""Packed per-trial results: packing, resuming from a pack, damage named and rerun, the loader."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from reproduce_trials import Settings as ReproduceSettings
from tavc_agents.experiments import packs
from tavc_agents.experiments.files import MANIFEST, CorruptFileError
from tavc_agents.experiments.folders import LOCK_FILE
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.sweep import json_jobs, run_jobs

RAN: list[str] = []


@dataclass(frozen=True)
class Job:
    key: str
    x: float


def work(job: Job) -> dict[str, object]:
    RAN.append(job.key)
    return {"x": job.x, "square": job.x * job.x, "nan": math.nan, "text": f"t{job.key}"}


KIND = json_jobs(work, lambda j: j.key)
JOBS = [Job(f"job{k}", float(k)) for k in range(5)]


def swept(folder: Path, jobs: list[Job] = JOBS) -> list[str]:
    """Run (resume) `jobs` in `folder` in this process; the keys that ran."""
    RAN.clear()
    run_jobs(jobs, KIND, folder, workers=1)
    return list(RAN)


@pytest.fixture
def packed(tmp_path: Path) -> Path:
    swept(tmp_path)
    before = packs.load_trials(tmp_path)
    done = packs.pack_folder(tmp_path)
    assert (done.trials, done.moved) == (5, 5)
    assert packs.load_trials(tmp_path) == before or _same_text(packs.load_trials(tmp_path), before)
    return tmp_path


def _same_text(a: object, b: object) -> bool:
    return json.dumps(a) == json.dumps(b)  # NaN != NaN, so compare as text


def test_packing_leaves_one_checked_file_and_the_same_records(packed: Path) -> None:
    # besides the lock file of the sweep and of the packing (folders.LOCK_FILE)
    assert sorted(p.name for p in packed.iterdir()) == [LOCK_FILE, MANIFEST, packs.PACK]
    lines = (packed / packs.PACK).read_text().splitlines()
    assert [json.loads(line)["key"] for line in lines] == [f"job{k}" for k in range(5)]
    assert (packed / MANIFEST).read_text().endswith(f"  {packs.PACK}\n")
    records = packs.load_trials(packed)
    assert records[2]["key"] == "job2" and records[2]["result"]["square"] == 4.0


def test_a_sweep_resumes_every_packed_job(packed: Path) -> None:
    assert swept(packed) == []
    assert not list(packed.glob("*.json"))


def test_a_damaged_line_is_named_and_no_line_of_its_pack_is_trusted(
    packed: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A damaged line means the pack no longer matches its manifest entry: the damaged line is
    named, and no line of that pack is used (a removed or re-checksummed line beside it would
    otherwise pass), so every job runs again; packing then replaces the pack."""
    pack = packed / packs.PACK
    pack.write_text(pack.read_text().replace('"square":9.0', '"square":9.5'))
    assert swept(packed) == [f"job{k}" for k in range(5)]
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 5
    assert all(
        "does not match its entry in CHECKSUMS.sha256 (1 of its lines damaged)" in e for e in err
    )
    assert err[3].endswith("running run 'job3' again")
    with pytest.raises(CorruptFileError):  # the rerun's loose files stand in, the pack is bad
        packs.find(packed, "job3")
    with pytest.raises(CorruptFileError, match="none of its lines is used"):
        packs.load_trials(packed)  # a line removed beside the damage would be missing unseen
    assert packs.pack_folder(packed).moved == 5  # packed in, replacing the damaged pack
    assert packs.load_trials(packed)[3]["result"]["square"] == 9.0
    assert packs.find(packed, "job3") is not None and swept(packed) == []


def test_a_removed_line_is_caught_even_beside_a_damaged_one(packed: Path) -> None:
    """Defect 6: the pack-wide digest was skipped as soon as one line was damaged, so a line
    removed beside it went unreported (the loader returned four trials of five)."""
    pack = packed / packs.PACK
    lines = pack.read_text().splitlines(keepends=True)
    lines[0] = lines[0].replace('"square":0.0', '"square":0.5')  # damaged: its checksum fails
    pack.write_text("".join(lines[:2] + lines[3:]))  # and job2's line removed
    swept(packed, [JOBS[0]])  # the damaged line's job runs again, loose; job2 has no loose file
    with pytest.raises(CorruptFileError, match=r"does not match its entry in CHECKSUMS\.sha256"):
        packs.load_trials(packed)


def test_an_edited_line_with_its_checksum_recomputed_is_not_used_beside_a_damaged_one(
    packed: Path,
) -> None:
    """Defect 6: with another line damaged, a line edited and re-checksummed was used."""
    pack = packed / packs.PACK
    lines = pack.read_text().splitlines(keepends=True)
    lines[0] = lines[0][:40] + "#" + lines[0][41:]  # damaged
    forged = json.loads(lines[1])
    forged["data"]["result"]["square"] = 99.0
    del forged["sha256"]
    lines[1] = packs._line(forged["key"], forged["data"]) + "\n"  # a valid line, recomputed
    pack.write_text("".join(lines))
    with pytest.raises(CorruptFileError, match="so none of its lines is used"):
        packs.find(packed, "job1")
    swept(packed, [JOBS[0]])  # the damaged line's job runs again, loose
    with pytest.raises(CorruptFileError, match="so none of its lines is used"):
        packs.load_trials(packed)


def test_a_removed_line_is_caught_by_the_manifest(packed: Path) -> None:
    pack = packed / packs.PACK
    lines = pack.read_text().splitlines(keepends=True)
    pack.write_text("".join(lines[:2] + lines[3:]))
    with pytest.raises(CorruptFileError, match="damaged, added, removed, reordered or edited"):
        packs.load_trials(packed)
    with pytest.raises(CorruptFileError, match="is not listed in"):
        (packed / MANIFEST).write_text("")
        packs.load_trials(packed)


def test_a_packed_job_run_with_other_settings_is_refused_naming_its_line(packed: Path) -> None:
    with pytest.raises(ValueError, match=r"pack\.jsonl, line 2 \(job1\) holds run 'job1' run with"):
        swept(packed, [Job("job1", 7.0)])


def test_packing_refuses_a_corrupt_file_and_deletes_nothing(tmp_path: Path) -> None:
    swept(tmp_path)
    (tmp_path / "job1.json").write_text('{"record": ')
    with pytest.raises(CorruptFileError, match=r"job1\.json"):
        packs.pack_folder(tmp_path)
    assert len(list(tmp_path.glob("*.json"))) == 5 and not (tmp_path / packs.PACK).exists()


def test_new_jobs_are_packed_in_after_an_update(packed: Path) -> None:
    more = [*JOBS, Job("job5", 5.0)]
    assert swept(packed, more) == ["job5"]
    assert [p.name for p in packed.glob("*.json")] == ["job5.json"]
    [done] = packs.pack_new(packed)
    assert (done.trials, done.moved) == (6, 1)
    assert swept(packed, more) == [] and not list(packed.glob("*.json"))


def test_columns_are_arrays_where_the_values_are_numbers() -> None:
    records = [
        {"key": "a", "n": 1, "ok": True, "r": {"v": 0.5, "w": [1, 2]}},
        {"key": "b", "n": 2, "ok": False, "r": {"v": None}},
    ]
    cols = packs.columns(records)
    assert cols["key"] == ["a", "b"]
    assert cols["n"].dtype == np.int64 and cols["ok"].dtype == bool  # type: ignore[union-attr]
    np.testing.assert_array_equal(cols["r.v"], [0.5, np.nan])
    assert cols["r.w"] == [[1, 2], None]


def test_a_packed_trial_is_read_by_path_and_found_by_pattern(tmp_path: Path) -> None:
    trial = TrialResult(
        seed=0, label="t", env_kwargs={}, agents=["robot_0"], speed_classes=["fast"],
        speeds=[0.3], values=[1.0], convergence_s=1.0, measured_s=1.0, end_s=2.0,
        initial_circuits=[0], changes=[(1.5, 0, 1)], spec={"key": "t"},
    )  # fmt: skip
    folder = tmp_path / "trials"
    folder.mkdir()
    trial.save(folder / "t.json")
    packs.pack_folder(folder)
    assert packs.is_saved(folder / "t.json") and not packs.is_saved(folder / "u.json")
    assert packs.load_trial(folder / "t.json") == trial
    assert packs.saved_paths(str(folder / "*.json")) == [str(folder / "t.json")]
    assert ReproduceSettings(patterns=(str(tmp_path / "*" / "*.json"),)).paths() == [
        str(folder / "t.json")
    ]
    with pytest.raises(FileNotFoundError, match="is not packed"):
        packs.read_saved(folder / "u.json")


def test_the_command_packs_and_refuses_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert packs.main([]) == 2
    assert packs.main([str(tmp_path / "nowhere")]) == 2
    assert "folder of trials" in capsys.readouterr().err
    swept(tmp_path)
    assert packs.main([str(tmp_path)]) == 0
    assert "5 loose files packed and deleted" in capsys.readouterr().out
