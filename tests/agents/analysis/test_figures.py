"""Figures stand alone. Every saved figure already passes `tests.helpers.figure_problems` (the
session-wide hook in tests/conftest.py: labelled axes, bars from zero, legends); here a figure
function draws into a file and the figure is kept for the stricter checks of its own."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

pytest.importorskip("matplotlib", reason="figures need the plot extra: pip install -e '.[plot]'")
import matplotlib.figure

import allocators
import interference
import leaderboard
import table1
from arena_analysis import plot_interference, read_group_rows
from tavc_agents import learning_runs
from tavc_agents.analysis.plots import allocation_timeline, learning_curve, redraw_learning_curve
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.learning_runs import CurveRow, Evaluation, LearningRun
from tests.helpers import figure_problems

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture
def saved(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    figures: list[Any] = []
    original = matplotlib.figure.Figure.savefig

    def keep(self: Any, *args: Any, **kwargs: Any) -> None:
        figures.append(self)
        original(self, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", keep)
    return figures


def check_axes(ax: Any) -> None:
    """Beyond the hook: bars start exactly at zero, and a legend belongs to its own axes."""
    assert not figure_problems(ax.figure)
    if any(type(c).__name__ == "BarContainer" for c in ax.containers):
        # bars start at zero, so their heights compare as ratios
        assert ax.get_ylim()[0] == 0.0
    lines = [line for line in ax.get_lines() if not line.get_label().startswith("_")]
    if len(lines) > 1:
        assert ax.get_legend() is not None, "several series without a legend"


def test_table1_performance_bars_start_at_zero(saved: list[Any], tmp_path: Path) -> None:
    by = {
        c: [SimpleNamespace(performance=p + 0.001 * k) for k in range(3)]
        for c, p in (("softmax", 0.112), ("epsilon", 0.109), ("random", 0.100))
    }
    names = {c: f"{c} (details)" for c in by}
    table1.plot_performance(by, names, tmp_path / "performance.png")  # type: ignore[arg-type]
    assert (tmp_path / "performance.png").stat().st_size > 0
    for ax in saved[-1].axes:
        check_axes(ax)


def test_learning_curve_has_units_legends_and_zero_based_axes(
    saved: list[Any], tmp_path: Path
) -> None:
    run = LearningRun("demo", "a demo run", {"preset": "dahl2004"}, {})
    for step, perf in ((100, 0.10), (200, 0.11)):
        run.curve.append(CurveRow(step, 1.0, Evaluation(0, 1.0, perf, 0.5, 0.4, 2.0)))
    learning_curve(learning_runs.curve_rows(run), run.title, tmp_path / "curve.png")
    for ax in saved[-1].axes:
        check_axes(ax)
        assert ax.get_ylim()[0] == 0.0


def test_learning_curve_redraws_from_a_saved_run_with_readable_step_ticks(
    saved: list[Any], tmp_path: Path
) -> None:
    """A committed run folder (curve.csv + evaluation.md) redraws without training; 200,000
    steps read as 0, 50k, ... rather than six-digit labels that overlap."""
    folder = ROOT / "benchmarks/results/marl/rllib_ppo_dahl2004"
    redraw_learning_curve(folder, tmp_path / "curve.png")
    figure = saved[-1]
    assert figure.get_suptitle().startswith("RLlib PPO")
    for ax in figure.axes:
        check_axes(ax)
        ax.figure.canvas.draw()
        labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
        assert labels and all(len(text) <= 4 for text in labels), labels
    with pytest.raises(ValueError, match="learning run folder"):
        (tmp_path / "curve.csv").write_text("step,performance\n")
        (tmp_path / "evaluation.md").write_text("no heading\n")
        redraw_learning_curve(tmp_path, tmp_path / "x.png")


def test_interference_figure_names_its_arena_and_starts_task_times_at_zero(
    saved: list[Any], tmp_path: Path
) -> None:
    runs = read_group_rows(ROOT / "benchmarks/results/interference_runs.csv")
    findings = interference.analyse(runs, list(range(5)))
    plot_interference(
        tmp_path / "interference.png", findings.rows, findings.cross, 1.15, "arena X", "arena Y"
    )
    curve, ratio, fast, slow = saved[-1].axes[:4]
    for ax in (curve, ratio):
        check_axes(ax)
    assert curve.get_ylim()[0] == 0.0 and "arena Y" in curve.get_title()
    assert "arena X" in fast.get_title() and "arena X" in slow.get_title()
    assert ratio.get_ylim()[0] <= 1.0 <= ratio.get_ylim()[1]  # the labelled no-slow-down line


def test_differentiation_figure_draws_every_source_and_says_what_is_pending(
    saved: list[Any], tmp_path: Path
) -> None:
    from twin_curve import Curve, PhysicsPoint, differentiation_figure

    curve = Curve("softmax_T0.005", [0.8, 1.0, 1.5], [0.1, 0.05, -0.1], [0.0, 0.0, -0.2], [0.2] * 3)
    cell = PhysicsPoint("softmax_T0.005", "dahl2004", 1.85, 1.84, 1.86, -0.04, -0.07, -0.01, 400)
    passing = PhysicsPoint("softmax_T0.005", "dahl2004_passing", 0.9, 0.8, 1.0, 0.05, 0.0, 0.1, 430)
    differentiation_figure([curve], [cell], [], [], tmp_path / "a.png", 2000)
    ax = saved[-1].axes[0]
    check_axes(ax)
    texts = [t.get_text() for t in ax.texts]
    assert any("pending" in t for t in texts) and any("dahl2004\ne = 1.85" in t for t in texts)
    assert ax.get_title() and ax.get_xlabel().startswith("crowding elasticity e")
    hlines = [ln for ln in ax.get_lines() if list(ln.get_ydata()) == [0.0, 0.0]]
    vlines = [ln for ln in ax.get_lines() if list(ln.get_xdata()) == [1.0, 1.0]]
    assert hlines and vlines  # the zero line and e = 1
    differentiation_figure([curve], [cell], [passing], [passing], tmp_path / "b.png", 2000)
    ax = saved[-1].axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "dahl2004_passing: twin prediction" in labels
    assert "dahl2004_passing: physics result" in labels
    assert not any("pending" in t.get_text() for t in ax.texts)


def test_leaderboard_draws_four_panels_to_a_row_labelled_on_the_outside(
    saved: list[Any], tmp_path: Path
) -> None:
    scenarios = ["dahl2004", "passing", "bad_start", "priority_shifts", "breakdowns"]
    order = ["static", "softmax_tavc", "random"]
    cells = {
        (a, k): (v, v - 0.1, v + 0.1)
        for a, v in zip(order, (0.9, 0.3, 0.0))
        for k in (*scenarios, "suite")
    }
    leaderboard.draw(tmp_path / "lb.png", order, scenarios, cells)
    axes = [ax for ax in saved[-1].axes if ax.get_visible()]
    assert len(axes) == 6 and len(saved[-1].axes) == 8  # 2 x 4, the last row's two spare hidden
    rows = sorted({round(ax.get_position().y0, 3) for ax in axes})
    assert len(rows) == 2
    assert [ax.get_ylabel() for ax in axes] == ["allocator", "", "", "", "allocator", ""]
    # every column's lowest panel names the x axis: the third and fourth's are in the first row
    assert [ax.get_xlabel() for ax in axes] == ["", "", *["IQM score"] * 4]
    assert [t.get_text() for t in axes[0].get_yticklabels()] == order
    for ax in axes:
        check_axes(ax)


def test_allocators_y_label_fits_in_the_figure(saved: list[Any], tmp_path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    rows = [
        {
            "preset": p,
            "label": f"allocator {k} (a long label)",
            "fraction_of_optimum": str(0.8 + 0.01 * k),
            "fraction_of_optimum_low": str(0.78 + 0.01 * k),
            "fraction_of_optimum_high": str(0.82 + 0.01 * k),
            "allocation_value_fraction": str(0.85),
        }
        for p in ("dahl2004", "three_circuits_three_classes")
        for k in range(11)
    ]
    allocators.plot(rows, tmp_path / "a.png")  # text numbers, as a written allocators.csv has
    fig = saved[-1]
    label = fig.axes[0].yaxis.label
    box = label.get_window_extent(FigureCanvasAgg(fig).get_renderer())
    assert label.get_text().startswith("fraction of the model optimum")
    assert box.x0 >= 0 and box.y0 >= 0 and box.y1 <= fig.bbox.height  # nothing cut off
    for ax in fig.axes:
        check_axes(ax)


def test_timeline_rows_are_robots_and_the_trial_names_its_panel(
    saved: list[Any], tmp_path: Path
) -> None:
    trial = TrialResult(
        seed=0,
        label="hand-made",
        env_kwargs={},
        agents=[f"robot_{i}" for i in range(4)],
        speed_classes=["fast", "fast", "slow", "slow"],
        speeds=[0.3, 0.3, 0.2, 0.2],
        values=[2.0, 1.0],
        convergence_s=3600.0,
        measured_s=3600.0,
        end_s=7200.0,
        initial_circuits=[0, 0, 1, 1],
    )
    allocation_timeline({"softmax": trial, "random": trial}, tmp_path / "t.png")
    axes = saved[-1].axes
    assert [ax.get_ylabel() for ax in axes] == ["robot", "robot"]
    assert [ax.get_title(loc="left") for ax in axes] == ["softmax", "random"]
