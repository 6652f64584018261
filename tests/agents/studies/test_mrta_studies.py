"""Smoke runs of the issue-4 benchmarks at a tiny size, chained as a researcher would run them:
`tavc_model.py` measures a model into a temporary folder, `allocators.py` and `vacancy_chain.py`
use it. Checks the outputs and the measures that have an exact answer (static allocation at the
model optimum has exactly the optimum's model value, never refills a vacancy, and breaks a fast
robot)."""

from __future__ import annotations

import contextlib
import csv
import importlib
import io
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

BENCHMARKS = Path(__file__).resolve().parents[3] / "benchmarks"


def load(name: str) -> ModuleType:
    sys.path.insert(0, str(BENCHMARKS))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(BENCHMARKS))


def quietly(module: ModuleType, argv: list[str]) -> str:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        module.main(argv)
    return buf.getvalue()


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def model_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    out = tmp_path_factory.mktemp("model")
    argv = ["--seeds", "1", "--warmup-min", "1", "--measured-h", "0.05", "--check-seeds", "2"]
    quietly(load("tavc_model"), [*argv, "--top", "1", "--workers", "1", "--out", str(out)])
    yield out


def test_model_outputs(model_run: Path) -> None:
    model = json.loads((model_run / "model.json").read_text())
    assert model["classes"] == ["fast", "slow"] and model["team"] == [3, 3]
    rates = model["rates"]
    assert len(rates) == 2 and len(rates[0]) == 4 and len(rates[0][0]) == 4
    assert rates[0][0][0] == 0.0 and rates[0][3][0] > rates[0][1][0] > 0.0
    slots = rows(model_run / "slot_values.csv")
    assert {r["joining"] for r in slots} == {"fast", "slow"}
    check = rows(model_run / "check.csv")
    # the optimum and its two neighbours (a fast robot out, a slow robot in), best first
    assert len(check) == 3 and check[0]["model_rank"] == "1"
    predicted = [float(r["predicted"]) for r in check]
    assert predicted == sorted(predicted, reverse=True)
    for r in check:
        assert 0.5 < float(r["measured_over_predicted"]) < 1.5
    assert "Spearman" in (model_run / "check.md").read_text()


def test_allocators_against_the_model(model_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "allocators"
    argv = ["--presets", "dahl2004", "--trials", "2", "--convergence-h", "0.05"]
    argv += ["--measured-h", "0.05", "--workers", "1", "--out", str(out)]
    printed = quietly(load("allocators"), [*argv, "--model", str(model_run / "model.json")])
    summary = {r["allocator"]: r for r in rows(out / "allocators.csv")}
    assert set(summary) == {
        "random",
        "epsilon_tavc",
        "softmax_tavc",
        "response_threshold",
        "auction",
        "greedy",
        "static",
    }
    assert float(summary["static"]["allocation_value_fraction"]) == pytest.approx(1.0)
    assert float(summary["static"]["switches_per_robot_h"]) == 0.0
    assert float(summary["random"]["vs_random"]) == pytest.approx(1.0)
    assert len(rows(out / "trials.csv")) == 14
    assert "### dahl2004" in printed and "fraction of optimum" in printed


def test_vacancy_chain(model_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "vacancy"
    argv = ["--trials", "2", "--convergence-h", "0.05", "--phase-h", "0.05", "--workers", "1"]
    quietly(
        load("vacancy_chain"), [*argv, "--out", str(out), "--model", str(model_run / "model.json")]
    )
    trials = rows(out / "trials.csv")
    assert len(trials) == 10
    static = [r for r in trials if r["allocator"] == "static"]
    for r in static:
        assert r["broken_class"] == "fast" and r["on_high_before"] == "3"
        # never back to full strength: infinite, written as an empty CSV cell
        assert r["recovery_min"] == "" and r["chain_moves"] == "0"
    summary = {r["allocator"]: r for r in rows(out / "vacancy_chain.csv")}
    assert summary["static"]["never_recovered"] == "2"
    assert "swap_w3_fraction" in summary["greedy"]
