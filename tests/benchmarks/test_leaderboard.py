"""The leaderboard: the interquartile mean and its stratified bootstrap, a short run end to end
(every allocator on two scenarios, normalised by the committed references), and the redraw of the
committed figure (`--figure-only`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import leaderboard as study
from tavc_agents import evaluation
from tavc_agents.experiments.study import RESULTS_DIR
from tests.helpers import check_figure_only


def test_the_iqm_is_the_mean_of_the_middle_half() -> None:
    assert evaluation.iqm([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 100.0]) == pytest.approx(3.5)
    assert evaluation.iqm([1.0, 2.0, 3.0, 4.0]) == pytest.approx(2.5)


def test_the_stratified_interval_holds_the_point_and_narrows_with_more_seeds() -> None:
    rng = np.random.default_rng(0)
    few = [list(rng.normal(0.5, 0.2, 8)), list(rng.normal(0.8, 0.2, 8))]
    many = [list(rng.normal(0.5, 0.2, 200)), list(rng.normal(0.8, 0.2, 200))]
    point, low, high = study.iqm_ci(few, 2000, np.random.default_rng(1))
    assert low <= point <= high
    _, low_many, high_many = study.iqm_ci(many, 2000, np.random.default_rng(1))
    assert high_many - low_many < high - low
    # a constant group has no spread to resample
    assert study.iqm_ci([[0.3, 0.3], [0.3, 0.3]], 200, np.random.default_rng(0)) == (0.3, 0.3, 0.3)


def test_a_short_run_scores_every_allocator_on_every_scenario(tmp_path: Path) -> None:
    settings = study.Settings(
        quick=True, scenarios=("bad_start", "breakdowns"), workers=1, out=tmp_path
    )
    outcome = study.run(settings)
    summary = json.loads((tmp_path / "leaderboard.json").read_text())["summary"]
    assert {"random", "stay", "softmax_tavc", "epsilon_tavc", "static", "greedy"} <= set(summary)
    for entry in summary.values():
        assert set(entry) == {"bad_start", "breakdowns", "suite"}
        for cell in entry.values():
            assert cell["ci"][0] <= cell["iqm"] + 1e-12 <= cell["ci"][1] + 2e-12
    # stay never leaves the crowded start: below random there, by the references
    assert summary["stay"]["bad_start"]["iqm"] < 0.0
    assert "tavc/bad_start-v0" in outcome.text


def test_a_submitted_row_and_a_plugin_join_the_table(tmp_path: Path) -> None:
    """The researcher's path: a PettingZoo-style policy evaluated on the leaderboard's episodes,
    its row taken in beside the allocators; a row of other episodes is refused."""
    from tavc_agents import evaluate

    def stay(observations: Any, infos: Any) -> dict[str, int]:
        return {a: int(i["circuit"]) for a, i in infos.items() if i["action_required"]}

    scenarios = ("bad_start", "breakdowns")
    row = evaluate(stay, scenarios, seeds=2, episode_h=0.5, name="my stay")
    path = row.save(tmp_path / "row.json")
    out = tmp_path / "board"
    settings = study.Settings(quick=True, scenarios=scenarios, workers=1, out=out, rows=(path,))
    outcome = study.run(settings)
    summary = json.loads((out / "leaderboard.json").read_text())["summary"]
    assert "| my stay (submitted) |" in outcome.text
    # the same decisions on the same episodes: the submitted row scores exactly as `stay`
    mine, stay_row = summary["my stay (submitted)"], summary["stay"]
    assert {k: v["iqm"] for k, v in mine.items()} == {k: v["iqm"] for k, v in stay_row.items()}
    short = evaluate(stay, scenarios, seeds=2, episode_h=0.25).save(tmp_path / "short.json")
    with pytest.raises(ValueError, match=r"was run with episode_h = 0\.25"):
        study.run(study.Settings(quick=True, scenarios=scenarios, out=out, rows=(short,)))
    with pytest.raises(ValueError, match="plugins"):
        study.Settings(plugins=("no_such_allocator",))


def test_settings_refuse_a_missing_reference_and_one_seed(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="references"):
        study.Settings(references=tmp_path / "none.json")
    with pytest.raises(ValueError, match="seeds"):
        study.Settings(seeds=1)


def test_figure_only_redraws_the_committed_figure_two_rows_of_four(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib", reason="figures need the plot extra")
    committed = RESULTS_DIR / "leaderboard"
    width, height = check_figure_only(study.run, study.Settings, committed, study.FIGURE, tmp_path)
    # eight panels in two rows: readable at a page's width (one row of eight was 2112 x 516)
    assert width <= 1300 and height > 0.6 * width


def test_committed_deep_reports_join_beside_the_allocators_as_reported() -> None:
    """`--deep`: a deep_leaderboard report's headline cells, as its own summary has them, on the
    scenarios it trained on and nowhere else; a report of other episodes is refused."""
    folder = RESULTS_DIR / "deep_leaderboard_smdp_entropy0.03"
    own = json.loads((folder / study.DEEP_REPORT).read_text())["summary"]
    s = study.Settings(scenarios=("dahl2004", "bad_start", "three_circuits"), deep=(folder,))
    (row,) = study.deep_rows(s)
    assert row.runs >= 10 and row.decisions_per_run >= 1_000_000
    assert set(row.cells) == {n for n in s.scenarios if f"{n}/mappo" in own}
    for name, (iqm, low, high, readout) in row.cells.items():
        assert (iqm, [low, high], readout) == (
            own[f"{name}/mappo"]["iqm"],
            own[f"{name}/mappo"]["ci"],
            own[f"{name}/mappo"]["readout"],
        )
    text = study.deep_section(s, [row])
    assert f"| {row.name} |" in text and "(greedy)" in text
    with pytest.raises(ValueError, match="was scored on all evaluation seeds"):
        study.deep_rows(study.Settings(scenarios=("bad_start",), seeds=2, deep=(folder,)))
    with pytest.raises(ValueError, match="deep"):
        study.Settings(deep=(RESULTS_DIR / "leaderboard",))
