"""Smoke runs of the tavc_model, allocators and vacancy_chain studies at a tiny size, chained as a
researcher would run them: `benchmarks/tavc_model.py` measures a model into a temporary folder,
`benchmarks/allocators.py` and `benchmarks/vacancy_chain.py` use it. Checks the outputs and the
measures that have an exact answer (static allocation at the model optimum has exactly the
optimum's model value, never refills a vacancy, and breaks a fast robot), that sampled trials
re-run to the same `trials.csv` rows (and that a changed row is caught), that the studies record
the settings their committed reports show, and that bad settings are refused."""

from __future__ import annotations

import contextlib
import csv
import importlib.util
import io
import json
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import allocators
import tavc_model
import vacancy_chain
from tavc_agents.experiments.study import RESULTS_DIR
from tavc_agents.learners.network import Mlp
from tavc_agents.model import load_model
from tests.helpers import check_figure_only

ROOT = Path(__file__).resolve().parents[2]


def script(name: str) -> ModuleType:
    """The program `benchmarks/<name>.py` (benchmarks/ is on pytest's pythonpath)."""
    return importlib.import_module(name)


def quietly(name: str, argv: list[str]) -> str:
    """What `python benchmarks/<name>.py ARGV` prints (its exit code checked)."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        assert script(name).main(argv) == 0
    return buf.getvalue()


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def model_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    out = tmp_path_factory.mktemp("model")
    argv = ["--seeds", "1", "--warmup-min", "1", "--measured-h", "0.05", "--check-seeds", "2"]
    quietly("tavc_model", [*argv, "--top", "1", "--workers", "1", "--out", str(out)])
    yield out


ALLOCATORS_TINY = ["--presets", "dahl2004", "--trials", "2", "--convergence-h", "0.02"]
ALLOCATORS_TINY += ["--measured-h", "0.03", "--workers", "1"]
VACANCY_TINY = ["--trials", "2", "--convergence-h", "0.02", "--phase-h", "0.02", "--workers", "1"]


@pytest.fixture(scope="module")
def allocators_run(model_run: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    out = tmp_path_factory.mktemp("allocators")
    # a trained network stands in: random weights of the right shape (paper_id: 2 + 6 inputs)
    nets = tmp_path_factory.mktemp("marl")
    (nets / "tiny_dahl2004").mkdir()
    rng = np.random.default_rng(0)
    shapes = [(16, 8), (2, 16)]
    Mlp(
        tuple(rng.normal(size=s) for s in shapes), tuple(rng.normal(size=s[0]) for s in shapes)
    ).save(nets / "tiny_dahl2004" / "network.npz")
    argv = [*ALLOCATORS_TINY, "--out", str(out), "--model", str(model_run / "model.json")]
    argv += ["--networks", "tiny", "absent", "--network-dir", str(nets)]
    printed = quietly("allocators", argv)
    settings = allocators.Settings(
        presets=("dahl2004",),
        trials=2,
        convergence_h=0.02,
        measured_h=0.03,
        workers=1,
        out=out,
        model=(model_run / "model.json",),
        networks=("tiny", "absent"),
        network_dir=nets,
    )
    return {"out": out, "printed": printed, "settings": settings}


@pytest.fixture(scope="module")
def vacancy_run(model_run: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    out = tmp_path_factory.mktemp("vacancy")
    argv = [*VACANCY_TINY, "--out", str(out), "--model", str(model_run / "model.json")]
    printed = quietly("vacancy_chain", argv)
    settings = vacancy_chain.Settings(
        trials=2,
        convergence_h=0.02,
        phase_h=0.02,
        workers=1,
        out=out,
        model=model_run / "model.json",
    )
    return {"out": out, "printed": printed, "settings": settings}


def test_model_outputs(model_run: Path) -> None:
    model = json.loads((model_run / "model.json").read_text())
    assert model["classes"] == ["fast", "slow"] and model["team"] == [3, 3]
    rates = model["rates"]
    assert len(rates) == 2 and len(rates[0]) == 4 and len(rates[0][0]) == 4
    assert rates[0][0][0] == 0.0 and rates[0][3][0] > rates[0][1][0] > 0.0
    slots = rows(model_run / "slot_values.csv")
    assert {r["joining"] for r in slots} == {"fast", "slow"}
    groups = rows(model_run / "group_runs.csv")
    assert len(groups) == 2 * 15 and set(groups[0]) == {
        "circuit",
        "n_fast",
        "n_slow",
        "seed",
        "tasks_per_h",
        "escapes",
    }
    check = rows(model_run / "check.csv")
    # the optimum and its two neighbours (a fast robot out, a slow robot in), best first
    assert len(check) == 3 and check[0]["model_rank"] == "1"
    assert check[0]["key"] == "3-0_0-3"
    predicted = [float(r["predicted"]) for r in check]
    assert predicted == sorted(predicted, reverse=True)
    for r in check:
        assert 0.5 < float(r["measured_over_predicted"]) < 1.5
    assert "Spearman" in (model_run / "check.md").read_text()
    # trials are kept under cache/ with the provenance of the sweep that ran them
    assert (model_run / "cache" / "check" / "trials" / "3-0_0-3_s1.json").exists()
    recorded = json.loads((model_run / "cache" / "groups" / "provenance.json").read_text())
    assert recorded["settings"]["seeds"] == "1" and recorded["trials_run"] == 30


def test_allocators_against_the_model(allocators_run: dict[str, object]) -> None:
    out = allocators_run["out"]
    assert isinstance(out, Path)
    summary = {r["allocator"]: r for r in rows(out / "allocators.csv")}
    assert list(summary) == [
        "random",
        "stay",
        "epsilon_tavc",
        "softmax_tavc",
        "own_reward",
        "response_threshold",
        "auction",
        "greedy",
        "static",
        "network_tiny",  # (no network of the run 'absent': no row)
    ]
    assert float(summary["static"]["allocation_value_fraction"]) == pytest.approx(1.0)
    assert float(summary["stay"]["switches_per_robot_h"]) == 0.0
    # the start's model value is the same for every allocator (the same seeds, the same starts)
    assert len({r["start_value_fraction"] for r in summary.values()}) == 1
    assert float(summary["static"]["switches_per_robot_h"]) == 0.0
    assert float(summary["random"]["vs_random"]) == pytest.approx(1.0)
    trials = rows(out / "trials.csv")
    assert len(trials) == 20  # 10 allocators x 2 seeds
    assert [(r["allocator"], r["seed"]) for r in trials[:3]] == [
        ("random", "0"),
        ("random", "1"),
        ("stay", "0"),
    ]
    assert (out / "cache" / "trials" / "dahl2004__static_s1.json").exists()
    printed = allocators_run["printed"]
    assert isinstance(printed, str)
    assert "### dahl2004" in printed and "fraction of optimum" in printed


def test_allocator_trials_reproduce_their_rows(allocators_run: dict[str, object]) -> None:
    settings = allocators_run["settings"]
    assert isinstance(settings, allocators.Settings)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        checked = allocators.reproduce_rows(settings, 2, seed=3)
    assert len(checked) == 2 and all(same for _, same in checked)
    assert all(key.startswith("dahl2004__") for key, _ in checked)


def test_a_changed_row_is_caught(allocators_run: dict[str, object], tmp_path: Path) -> None:
    settings = allocators_run["settings"]
    assert isinstance(settings, allocators.Settings)
    saved = rows(settings.out_dir() / "trials.csv")
    static = [r for r in saved if r["allocator"] == "static"]
    changed = [{**r, "performance": str(float(r["performance"]) * (1 + 1e-12))} for r in static]
    with open(tmp_path / "trials.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(saved[0]))
        writer.writeheader()
        writer.writerows(changed)
    moved = allocators.Settings(**{**vars(settings), "out": tmp_path})
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        checked = allocators.reproduce_rows(moved, 1, seed=0)
    assert checked == [(checked[0][0], False)]


def test_vacancy_chain(vacancy_run: dict[str, object]) -> None:
    out = vacancy_run["out"]
    assert isinstance(out, Path)
    trials = rows(out / "trials.csv")
    assert len(trials) == 10
    static = [r for r in trials if r["allocator"] == "static"]
    for r in static:
        assert r["broken_class"] == "fast" and r["on_high_before"] == "3"
        # never back to full strength: infinite, written as an empty CSV cell
        assert r["recovery_min"] == "" and r["chain_moves"] == "0"
        broken = r["broken_robot"]
        assert (
            out / "cache" / "events" / "trials" / f"static_events_r{broken}_s{r['seed']}.json"
        ).exists()
    summary = {r["allocator"]: r for r in rows(out / "vacancy_chain.csv")}
    assert summary["static"]["never_recovered"] == "2"
    assert "swap_w3_fraction" in summary["greedy"]
    assert "## Breakdown" in str(vacancy_run["printed"])


def test_vacancy_chain_trials_reproduce_their_rows(vacancy_run: dict[str, object]) -> None:
    settings = vacancy_run["settings"]
    assert isinstance(settings, vacancy_chain.Settings)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        checked = vacancy_chain.reproduce_rows(settings, 1, seed=5)
    assert len(checked) == 1 and checked[0][1] and "_events_r" in checked[0][0]


def committed_settings(path: Path) -> dict[str, str]:
    settings: dict[str, str] = json.loads(path.read_text())["metadata"]["settings"]
    return settings


def test_recorded_settings_are_those_of_the_committed_reports() -> None:
    model = committed_settings(RESULTS_DIR / "tavc_model" / "dahl2004" / "check.json")
    assert tavc_model.Settings().recorded() == model
    three = tavc_model.Settings(preset="three_circuits_three_classes", seeds=2)
    path = RESULTS_DIR / "tavc_model" / "three_circuits_three_classes" / "slot_values.json"
    assert three.recorded() == committed_settings(path)
    recorded_now = {
        "allocators": allocators.Settings(update_reference=True).recorded(),
        "vacancy_chain": vacancy_chain.Settings(update_reference=True).recorded(),
    }
    for name, recorded in recorded_now.items():
        committed = committed_settings(RESULTS_DIR / name / f"{name}.json")
        # the default output folder is recorded as an absolute path, wherever the checkout is
        assert committed["out"].endswith(f"benchmarks/results/{name}")
        committed["out"] = str(RESULTS_DIR / name)
        if "network_dir" in committed:  # likewise the trained networks' folder
            assert committed["network_dir"].endswith("benchmarks/results/marl")
            committed["network_dir"] = str(RESULTS_DIR / "marl")
        assert recorded == committed and list(recorded) == list(committed)


def test_quick_sizes_and_folders() -> None:
    quick = allocators.Settings(quick=True)
    assert quick.reference_dir() == RESULTS_DIR / "allocators_quick"
    assert quick.recorded()["trials"] == "2" and quick.recorded()["measured_h"] == "1.0"
    vquick = vacancy_chain.Settings(quick=True)
    assert vquick.reference_dir() == RESULTS_DIR / "vacancy_chain_quick"
    assert vquick.times() == {"break": 3600.0, "repair": 7200.0, "swap": 10800.0, "end": 14400.0}


def test_trial_keys_keep_their_old_form() -> None:
    s = allocators.Settings()
    model = load_model("dahl2004")
    spec = allocators.trial_spec(s, model, "dahl2004", "softmax_tavc", 4)
    assert spec.key == "dahl2004__softmax_tavc_s4"
    assert dict(spec.tags) == {"preset": "dahl2004", "allocator": "softmax_tavc", "seed": 4}
    v = vacancy_chain.Settings()
    assert vacancy_chain.control_spec(v, model, "greedy", 2).key == "greedy_control_s2"
    events = vacancy_chain.events_spec(v, model, "greedy", 2, broken=1)
    assert events.key == "greedy_events_r1_s2" and len(events.events) == 3
    checks = tavc_model.check_specs(tavc_model.Settings(check_seeds=2), [((3, 0), (0, 3))])
    assert [c.key for c in checks] == ["3-0_0-3_s0", "3-0_0-3_s1"]


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: tavc_model.Settings(preset="nowhere"), "preset = 'nowhere' is invalid"),
        (lambda: tavc_model.Settings(seeds=0), "seeds = 0 is invalid"),
        (lambda: tavc_model.Settings(measured_h=0.0), "measured_h = 0.0 is invalid"),
        (lambda: allocators.Settings(trials=1), "trials = 1 is invalid"),
        (lambda: allocators.Settings(model=(Path("a.json"),)), "one path per preset"),
        (
            lambda: allocators.Settings(presets=("dahl2004",), model=(Path("/no/model.json"),)),
            "/no/model.json is missing",
        ),
        (lambda: vacancy_chain.Settings(phase_h=-1.0), "phase_h = -1.0 is invalid"),
        (lambda: vacancy_chain.Settings(convergence_h=0.0), "convergence_h = 0.0 is invalid"),
    ],
)
def test_bad_settings_are_refused(make: object, message: str) -> None:
    assert callable(make)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(".", r"\.")):
        make()


def test_a_bad_option_is_a_usage_error() -> None:
    err = io.StringIO()
    with (
        contextlib.redirect_stderr(err),
        contextlib.redirect_stdout(io.StringIO()),
        pytest.raises(SystemExit) as exit_,
    ):
        script("vacancy_chain").main(["--trials", "1"])
    assert exit_.value.code == 2 and "trials = 1 is invalid" in err.getvalue()


def test_allocators_figure_only_redraws_the_committed_figure(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib", reason="figures need the plot extra")
    committed = RESULTS_DIR / "allocators"
    width, height = check_figure_only(
        allocators.run, allocators.Settings, committed, allocators.FIGURE, tmp_path
    )
    assert (width, height) == (1440, 600)  # two panels of 6 x 5 inches at 120 dpi
