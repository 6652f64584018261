"""The twin among learners (`benchmarks/twin_learners.py`): its four stages end to end on a short
run, the logged physics trials identical to the committed ones of the same seed, and the
learner tables read back."""

from __future__ import annotations

import json
from pathlib import Path

import arena_runs
import twin_learners as study
from tavc_agents.experiments.files import read_record
from tavc_env.twin import InterferenceTables


def test_the_stages_run_end_to_end_on_a_short_run(tmp_path: Path) -> None:
    out = tmp_path / "run"
    for stage in ("logs", "audit", "predict"):
        assert study.main(["--stage", stage, "--quick", "--workers", "1", "--out", str(out)]) == 0
    tables = InterferenceTables.from_dict(read_record(out / "tables" / "dahl2004_passing.json"))
    assert tables.first_own_cells and len(tables.class_switch_costs) == 2
    report = json.loads((out / "twin_learners.json").read_text())
    sources = {r["source"] for r in report["summary"]["effects"]}
    assert sources == {"physics (committed)", *(f"twin: {v}" for v in study.VARIANTS)}
    assert report["summary"]["discrepancy"]["rerun_identical"]
    prediction = json.loads((out / "prediction.json").read_text())
    cells = prediction["summary"]["cells"]
    assert [(c["arena"], c["condition"]) for c in cells] == list(study.OUT_OF_SAMPLE)
    assert all(c["physics_trials"] >= 3 for c in cells)
    test = tmp_path / "test"
    args = ["--stage", "test", "--quick", "--workers", "1", "--out", str(test)]
    assert study.main([*args, "--prediction", str(out / "prediction.json")]) == 0
    rows = json.loads((test / "test.json").read_text())["summary"]["cells"]
    assert [r["trials"] for r in rows] == [3] * len(cells)
    # --interim: the report of the trials saved, none run
    (
        test
        / "trials"
        / f"{study.log_key(study.LogTrial(cells[0]['arena'], cells[0]['condition'], 2, 0.3, 0.2))}.json"
    ).unlink()
    interim = [
        *args,
        "--prediction",
        str(out / "prediction.json"),
        "--resume",
        str(test),
        "--interim",
    ]
    interim.remove("--out")
    interim.remove(str(test))
    assert study.main(interim) == 0
    rows = json.loads((test / "test.json").read_text())["summary"]["cells"]
    assert [r["trials"] for r in rows] == [2] + [3] * (len(cells) - 1)


def test_logged_trials_are_the_committed_trials() -> None:
    """The committed logs reproduce the committed physics trials of the same seeds exactly."""
    logs = study.load_trials(study.RESULTS_DIR / "twin_learners" / "logs")
    assert len(logs) == sum(study.LOG_CELLS.values())
    for arena, condition in study.LOG_CELLS:
        committed = study.committed_physics(arena, condition)
        for record in logs:
            job, result = record["record"], record["result"]
            if (job["arena"], job["condition"]) == (arena, condition):
                diff = float(result["fast_share"]) - float(result["slow_share"])
                assert diff == committed[int(job["seed"])]


def test_the_shape_check_compares_what_a_learner_is_paid() -> None:
    """The committed test report's check on the misses (`reward_shape`): per logged arena and
    class, E[1/t] on the high-value circuit and the others in physics and by the learner tables'
    lognormal; the twin's shape gives the ratio a choice turns on to within 0.002, and the
    ratios are those of the committed logs recomputed now."""
    report = json.loads((study.RESULTS_DIR / "twin_learners_test" / "test.json").read_text())
    shape = report["summary"]["reward_shape"]
    assert {(r["arena"], r["class"]) for r in shape} == {
        (a, c) for a, _ in study.LOG_CELLS for c in ("fast", "slow")
    }
    for row in shape:
        assert row["tasks"] > 10_000
        assert abs(row["physics_ratio"] - row["twin_ratio"]) < 0.002, row
    settings = study.Settings(stage="test", update_reference=True)
    again = {(r["arena"], r["class"]): r for r in study.reward_shape(settings)}
    for row in shape:
        assert again[(row["arena"], row["class"])]["physics_ratio"] == row["physics_ratio"]


def test_the_search_maps_its_eight_cells_and_decides_by_its_rule(tmp_path: Path) -> None:
    """`--stage search` on a short run, from the committed family tables: the rule's 8 cells, a
    cell a candidate exactly when its predicted interval lies above 0, and a plan (none, or the
    best candidate on fresh seeds) that the test stage can run."""
    out = tmp_path / "search"
    assert study.main(["--stage", "search", "--quick", "--workers", "1", "--out", str(out)]) == 0
    cells = json.loads((out / "search.json").read_text())["summary"]["cells"]
    assert len(cells) == 8
    assert {(c["arena"], c["condition"]) for c in cells} == {
        (a, c) for a in arena_runs.SEARCH_LEARNER_ARENAS for c in study.SEARCH_CONDITIONS
    }
    for c in cells:
        assert c["candidate"] == (c["learners_low"] > 0.0)
    plan = json.loads((out / "prediction.json").read_text())["summary"]["cells"]
    candidates = [c for c in cells if c["candidate"]]
    assert len(plan) == (1 if candidates else 0)
    if plan:
        assert plan[0]["learners"] == max(c["learners"] for c in candidates)
        assert plan[0]["first_seed"] == study.SEARCH_FIRST_SEED


def test_the_gap_stage_runs_its_pairs(tmp_path: Path) -> None:
    """`--stage gap` on a short run: every cell's pairs, and the residual table of the committed
    logs at T = 0.005 for the arenas of its cells."""
    out = tmp_path / "gap"
    assert study.main(["--stage", "gap", "--quick", "--workers", "1", "--out", str(out)]) == 0
    summary = json.loads((out / "gap.json").read_text())["summary"]
    assert [(c["arena"], c["condition"]) for c in summary["cells"]] == list(study.GAP_CELLS)
    assert all(c["pairs"] == 3 for c in summary["cells"])
    arenas = {r["arena"] for r in summary["residuals"]}
    assert arenas == {a for a, _ in study.GAP_CELLS}
    assert all(r["n"] >= 26 for r in summary["residuals"])
    pairs = {(r["arena"], r["pair"]) for r in summary["convoys"]}
    assert pairs == {
        (a, f"{c0}, then {c1}")
        for a in arenas
        for c0 in ("fast", "slow")
        for c1 in ("fast", "slow")
    }
    assert all(-1.0 <= r["mean"] <= 1.0 and r["pairs"] >= 10 for r in summary["convoys"])


def test_the_corrected_pay_multiplies_the_twins_draw_by_its_factor() -> None:
    """`CorrectedPayEnv` (stage `gap`): the same seed and actions as the twin-paid physics give
    the same motion and draws; a task after a robot's first reports its draw times the factor of
    its class, kind and period (here 2 for fast robots' stays on the high-value circuit and 3
    for every other task decided in the first hour, none later), a first task its draw."""
    import numpy as np
    import pytest

    import tavc_env
    from tavc_env import completed_task_s

    tables = study.learned_tables("dahl2004", study.Settings(stage="gap"))

    def factor_of(cls: str, kind: str) -> float:
        return 2.0 if (cls, kind) == ("fast", "stay high") else 3.0

    kinds = ("stay high", "stay low", "into high", "into low")
    factors = [(c, k, 0, factor_of(c, k)) for c in tables.classes for k in kinds]
    limits = {"preset": "dahl2004", "max_sim_time_s": 5400.0}
    corrected = study.CorrectedPayEnv(tables, factors, **limits)
    paid = tavc_env.twin.twin_paid_parallel_env(tables=tables, **limits)
    _, infos = paid.reset(seed=4)
    corrected.reset(seed=4)
    agents, classes = paid.possible_agents, [r.speed_class for r in paid.config.robots]
    high = int(np.argmax([c.value for c in paid.config.circuits]))
    last = {a: int(infos[a]["circuit"]) for a in agents}
    task_of: dict[str, tuple[float, int]] = {}  # agent -> (decided at, circuit before)
    firsts, checked, step = set(agents), 0, 0
    while paid.agents:
        wanted = {a: (i + step // 5) % 2 for i, a in enumerate(agents)}
        actions = {a: wanted[a] for a in agents if infos[a]["action_required"]}
        for a, c in actions.items():
            task_of[a], last[a] = (paid.sim_time_s, last[a]), c
        _, _, _, _, infos = paid.step(actions)
        _, _, _, _, mine = corrected.step(actions)
        step += 1
        assert np.array_equal(paid.sim.positions(), corrected.sim.positions())
        for i, a in enumerate(agents):
            t = completed_task_s(infos[a])
            if t is None:
                continue
            at_s, before = task_of[a]
            circuit = infos[a]["circuit"]
            kind = ("stay " if before == circuit else "into ") + (
                "high" if circuit == high else "low"
            )
            factor = 1.0 if a in firsts or at_s >= 3600.0 else factor_of(classes[i], kind)
            firsts.discard(a)
            assert completed_task_s(mine[a]) == pytest.approx(t * factor, rel=1e-12)
            checked += factor != 1.0
    assert checked >= 10
