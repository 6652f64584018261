"""The command line refuses out-of-range hours, seeds and paths before any work (issue 28, item
5): `tavc trial`, `tavc plot` and every study's settings (the programs of benchmarks/),
each in one line with exit code 2, never a traceback from deep inside a trial."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tavc_agents.experiments import limits
from tavc_agents.experiments.study import StudySettings
from tavc_agents.learners.network import Mlp
from tests.agents.test_cli import TINY, run
from tests.helpers import study_programs


def _one_line_error(command: str, err: str) -> str:
    """The error line of an argparse refusal (after the command's usage lines)."""
    lines = err.strip().splitlines()
    assert lines[0].startswith(f"usage: tavc {command}"), err
    errors = [line for line in lines if line.startswith(f"tavc {command}: error: ")]
    assert len(errors) == 1, err
    return errors[0]


@pytest.fixture(scope="module")
def trial_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("trial") / "t.json"
    code, _, err = run(["trial", "--allocator", "random", *TINY, "--out", str(path)])
    assert code == 0, err
    return path


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["trial", "--measured-h", "1e308"], "--measured-h = 1e+308; allowed: a finite number > 0"),
        (["trial", "--convergence-h", "1e308"], "--convergence-h = 1e+308; allowed: a finite"),
        (["trial", "--measured-h", "100001"], "and <= 100000 (simulated hours)"),
        (["trial", "--measured-h=-inf"], "--measured-h = -inf; allowed"),
        (["trial", "--convergence-h", "inf"], "--convergence-h = inf; allowed"),
        (["trial", "--measured-h", "nan"], "--measured-h = nan; allowed"),
        (["trial", "--seed", "-1"], "--seed = -1; allowed: an integer in [0, 2**63 - 1]"),
        (["trial", "--seed", "1" + "0" * 25], f"--seed = 1{'0' * 25}; allowed: an integer in"),
        (["trial", "--seed", str(2**63)], f"--seed = {2**63}; allowed"),
        (["record", "--seed", "-5"], "--seed = -5; allowed"),
        (
            ["record", "--minutes", "1e308"],
            "--minutes = 1e+308; allowed: a finite number > 0 and <=",
        ),
        (
            ["trial", "--allocator", "network", "--param", "weights=/nonexistent.npz"],
            "network file /nonexistent.npz does not exist; allowed: an .npz written by Mlp.save",
        ),
        (["plot", "timeline", "/"], "/ is a folder; allowed: a trial JSON file"),
        (["plot", "q", "/"], "/ is a folder; allowed: a trial JSON file"),
    ],
)
def test_out_of_range_values_are_refused_in_one_line(argv: list[str], message: str) -> None:
    code, out, err = run(argv)
    assert code == 2
    assert message in _one_line_error(argv[0], err)
    assert out == "" and "sim s" not in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("window", "message"),
    [
        (["--from-h", "nan"], "--from-h = nan; allowed: a finite number >= 0"),
        (["--to-h", "inf"], "--to-h = inf; allowed"),
        (["--from-h", "-1"], "--from-h = -1.0; allowed"),
        (["--from-h", "2", "--to-h", "1"], "--from-h = 2.0 and --to-h = 1.0 are invalid together"),
        (["--from-h", "1", "--to-h", "1"], "allowed: --from-h below --to-h"),
    ],
)
def test_the_timeline_window_is_checked(
    window: list[str], message: str, trial_file: Path, tmp_path: Path
) -> None:
    target = tmp_path / "x.png"
    code, _, err = run(["plot", "timeline", str(trial_file), *window, "--out", str(target)])
    assert code == 2 and message in _one_line_error("plot", err)
    assert not target.exists()


def test_a_network_npy_and_a_network_of_another_arena_are_refused_before_the_trial(
    tmp_path: Path,
) -> None:
    single = tmp_path / "w.npy"
    np.save(single, np.zeros((2, 8)))
    code, _, err = run(["trial", "--allocator", "network", "--param", f"weights={single}", *TINY])
    assert code == 2 and "is a single .npy array, not a network" in _one_line_error("trial", err)
    other = Mlp((np.zeros((2, 9)),), (np.zeros(2),)).save(tmp_path / "other.npz")  # 9 inputs, not 8
    code, _, err = run(["trial", "--allocator", "network", "--param", f"weights={other}", *TINY])
    line = _one_line_error("trial", err)
    assert code == 2 and f"network file {other}: inputs = 9 is invalid; allowed: 8" in line
    assert "sim s" not in err  # no progress bar: the trial never started
    fits = Mlp((np.zeros((2, 8)),), (np.zeros(2),)).save(tmp_path / "fits.npz")
    code, out, err = run(["trial", "--allocator", "network", "--param", f"weights={fits}", *TINY])
    assert code == 0, err
    assert "network on dahl2004" in out


def _study_error(err: str) -> str:
    """A study's refusal (the settings parser's box) as one line of text."""
    return " ".join(err.replace("│", " ").replace("╭", " ").replace("╰", " ").split())


def run_program(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str, str]:
    """`python benchmarks/ARGV[0].py ARGV[1:]`, in this process: exit code, stdout, stderr."""
    try:
        code = study_programs()[argv[0]].main(argv[1:])
    except SystemExit as stop:
        code = int(stop.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["differentiation", "--seed", "-1"], "seed = -1 is invalid; allowed: an integer in [0,"),
        (["table1", "--seed", "1" + "0" * 25], f"seed = 1{'0' * 25} is invalid"),
        (["liveness", "--arena-seed", str(2**63)], f"arena_seed = {2**63} is invalid"),
        (["long_run", "--seed0", "-3"], "seed0 = -3 is invalid"),
        (["differentiation", "--measured-h", "1e308"], "measured_h = 1e+308 is invalid"),
        (["differentiation", "--convergence-h", "nan"], "convergence_h = nan is invalid"),
        (["interference", "--hours", "inf"], "hours = inf is invalid"),
        (["passing", "--e-hours", "-1"], "e_hours = -1.0 is invalid"),
    ],
)
def test_a_studys_seeds_and_hours_are_refused_before_any_work(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run_program(capsys, [*argv, "--out", str(tmp_path / "out")])
    assert code == 2
    assert message in _study_error(err)
    assert "Writing to" not in out and not (tmp_path / "out").exists()


def test_the_ray_backend_without_ray_is_refused_when_the_settings_are_read(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(limits, "ray_installed", lambda: False)
    argv = ["table1", "--quick", "--backend", "ray", "--out", str(tmp_path)]
    code, out, err = run_program(capsys, argv)
    assert code == 2 and "Writing to" not in out
    assert "backend = 'ray' is invalid: Ray is not installed (pip install 'tavc-env[ray]')" in (
        _study_error(err)
    )
    import table1 as module

    with pytest.raises(ValueError, match="backend = 'ray' is invalid"):
        module.Settings(backend="ray", out=tmp_path)
    monkeypatch.setattr(limits, "ray_installed", lambda: True)  # with Ray: accepted
    assert module.Settings(backend="ray", out=tmp_path).backend == "ray"


def _every_studys_settings() -> list[type[StudySettings]]:
    """The settings class of every study program of benchmarks/."""
    found = []
    for module in study_programs().values():
        settings = getattr(module, "Settings", None)
        if isinstance(settings, type) and issubclass(settings, StudySettings):
            found.append(settings)
    return found


def test_every_studys_seed_and_hour_fields_are_checked() -> None:
    """The check goes by field name: every study's seed and hour fields match it and are of the
    types it checks (a new field named otherwise would escape it; this lists them)."""
    classes = _every_studys_settings()
    assert len(classes) >= 20
    checked = set()
    for settings in classes:
        for field in dataclasses.fields(settings):
            n = field.name
            if n in ("seed", "seed0") or n.endswith("_seed"):
                checked.add(n)
                assert field.type in (int, "int"), (settings, n, field.type)
            elif n == "hours" or n.endswith(("_hours", "_h")):
                checked.add(n)
                assert field.type in (float, "float", "float | None"), (settings, n, field.type)
    assert {"seed", "seed0", "arena_seed", "hours", "measured_h", "e_hours", "episode_h"} <= checked


def test_a_setting_left_to_its_default_is_not_checked() -> None:
    import scenarios

    assert scenarios.Settings(out=Path("unused")).episode_h is None
    with pytest.raises(ValueError, match=r"^episode_h = inf is invalid; allowed: a finite number"):
        scenarios.Settings(episode_h=float("inf"), out=Path("unused"))


def test_the_limits_themselves() -> None:
    assert limits.valid_seed(0) and limits.valid_seed(2**63 - 1) and limits.valid_seed(np.int64(3))
    for bad in (-1, 2**63, True, 1.0, "3", None):
        assert not limits.valid_seed(bad)
    assert limits.valid_hours(0.0, zero=True) and not limits.valid_hours(0.0, zero=False)
    assert limits.valid_hours(limits.MAX_HOURS, zero=False)
    for bad in (limits.MAX_HOURS * 1.0001, float("nan"), float("inf"), -1e-9, 1e308, True):
        assert not limits.valid_hours(bad, zero=True)
