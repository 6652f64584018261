"""The `tavc` command: help a newcomer can follow, a trial with a progress bar and a summary,
recordings, the benchmark scripts behind `reproduce` / `bench`, and errors that say what is
allowed."""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import io
import subprocess
import sys
from pathlib import Path

import pytest

from tavc_agents.cli import main
from tavc_agents.experiments.runner import TrialResult

ROOT = Path(__file__).resolve().parents[2]
TINY = ["--convergence-h", "0.02", "--measured-h", "0.05"]


def run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as stop:
            code = int(stop.code or 0)
    return code, out.getvalue(), err.getvalue()


def test_console_script_is_installed_and_help_lists_every_command() -> None:
    scripts = importlib.metadata.entry_points(group="console_scripts")
    assert any(e.name == "tavc" and e.value == "tavc_agents.cli:main" for e in scripts)
    done = subprocess.run(
        [sys.executable, "-m", "tavc_agents.cli", "--help"],
        capture_output=True,
        text=True,
        check=True,
    )
    for command in ("trial", "record", "plot"):
        assert command in done.stdout
    assert "reproduce" not in done.stdout and "bench" not in done.stdout  # studies are programs


@pytest.mark.parametrize("command", ["trial", "record", "plot", "evaluate"])
def test_every_command_has_help(command: str) -> None:
    code, out, _ = run([command, "--help"])
    assert code == 0 and f"usage: tavc {command}" in out


def test_trial_prints_progress_and_a_summary_and_saves(tmp_path: Path) -> None:
    path = tmp_path / "trial.json"
    code, out, err = run(["trial", "--allocator", "random", *TINY, "--out", str(path)])
    assert code == 0
    assert "sim s" in err and "sim s" not in out  # the progress bar, on stderr
    assert "delivered value per robot per 10 s" in out
    assert "fast robots (3)" in out and "slow robots (3)" in out
    result = TrialResult.load(path)
    assert result.end_s == pytest.approx(0.07 * 3600)
    # the same seed through the CLI and the runner: the same trial
    code, _, _ = run(["trial", "--allocator", "random", *TINY, "--out", str(tmp_path / "b.json")])
    again = TrialResult.load(tmp_path / "b.json")
    assert again.changes == result.changes and again.delivery_time_s == result.delivery_time_s


def test_trial_takes_a_scenario(tmp_path: Path) -> None:
    path = tmp_path / "s.json"
    code, out, _ = run(
        ["trial", "--scenario", "bad_start", "--allocator", "random", *TINY, "--out", str(path)]
    )
    assert code == 0 and "random on scenario bad_start" in out
    result = TrialResult.load(path)
    assert result.env_kwargs == {"scenario": "bad_start"}
    assert result.initial_circuits == [1, 1, 1, 0, 1, 1]  # the scenario's bad start
    # a model-based allocator finds the scenario's reference model
    code, out, _ = run(["trial", "--scenario", "bad_start", "--allocator", "greedy", *TINY])
    assert code == 0 and "greedy on scenario bad_start" in out


def test_trial_with_parameters_overrides_and_a_team_allocator(tmp_path: Path) -> None:
    path = tmp_path / "t.json"
    argv = ["trial", "--allocator", "softmax_tavc", "--param", "temperature=0.02"]
    argv += ["--param", "init=paper", "--set", "source_service_s=10", *TINY, "--out", str(path)]
    assert run(argv)[0] == 0
    assert TrialResult.load(path).env_kwargs["source_service_s"] == 10
    # greedy needs the model: the committed one of the preset is found
    code, out, _ = run(["trial", "--allocator", "greedy", *TINY])
    assert code == 0 and "greedy on dahl2004" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["trial", "--param", "temperature"],
            "--param 'temperature' is invalid; allowed: KEY=VALUE",
        ),
        (["trial", "--measured-h", "0"], "--measured-h = 0.0; allowed: a finite number > 0"),
        (
            ["trial", "--convergence-h", "-1"],
            "--convergence-h = -1.0; allowed: a finite number >= 0",
        ),
        (["trial", "--allocator", "nope"], "invalid choice: 'nope'"),
        (
            ["trial", "--param", "bogus=1", *TINY],
            "allocator 'softmax_tavc' has no parameter bogus; allowed: temperature (default",
        ),
        (["trial", "--allocator", "auction", "--param", "bogus=1", *TINY], "no parameter bogus;"),
        (["trial", "--measured-h", "inf"], "--measured-h = inf; allowed: a finite number > 0"),
        (["trial", "--convergence-h", "nan"], "--convergence-h = nan; allowed: a finite number"),
        (["trial", *TINY, "--out", "/nonexistent/t.json"], "the folder /nonexistent does not"),
        (["trial", *TINY, "--out", "/dev/full"], "/dev/full is a character device"),
        (["trial", "--set", "wings=2", *TINY], "arena overrides = ['wings'] is invalid; allowed:"),
        (
            ["trial", "--scenario", "bad_start", "--preset", "dahl2004", *TINY],
            "arena = {'scenario': 'bad_start', 'preset': 'dahl2004'} is invalid; allowed: one of "
            "a scenario, a preset or a config",
        ),
        (
            ["trial", "--scenario", "bad_start", "--set", "dt=0.05", *TINY],
            "scenario 'bad_start' with arena overrides = ['dt'] is invalid; allowed: a scenario "
            "alone",
        ),
        (
            ["trial", "--scenario", "bad_stat", *TINY],
            "scenario = 'bad_stat' is invalid; allowed: a scenario (bad_start,",
        ),
        (["trial", "--set", "preset=dahl2004", *TINY], "--set preset=dahl2004 is invalid"),
        (
            ["trial", "--allocator", "greedy", "--preset", "dahl2004_homogeneous", *TINY],
            "allocator 'greedy' needs the TAVC model",
        ),
        (["record", "--out", "arena.mp4"], "allowed: a .gif (animation) or .png"),
        (
            ["trial", "--allocator", "static", "--model", "/nonexistent.json"],
            "/nonexistent.json is missing",
        ),
        (["trial", "--allocator", "static", "--model", __file__, *TINY], "could not be read"),
        (  # defect 10: a device was called "missing"
            ["trial", "--allocator", "static", "--model", "/dev/zero", *TINY],
            "/dev/zero is a character device, not a regular file",
        ),
        (  # defect 4: refused before the trial, not after it (the result was thrown away)
            ["trial", "--allocator", "random", *TINY, "--out", "/proc/x.json"],
            "/proc/x.json cannot be written (No such file or directory)",
        ),
        (
            ["trial", "--allocator", "random", *TINY, "--out", f"/tmp/{'x' * 300}.json"],
            "cannot be written (File name too long)",
        ),
        (  # defect 10: refused before the convergence ran
            ["trial", "--allocator", "random", "--convergence-h", "0.02", "--measured-h", "1e-300"],
            "measured_s = 3.6e-297 is invalid",
        ),
        (["record", "--fps", "1e9"], "--fps = 1000000000.0; allowed: a number in [0.01, 100]"),
        (["bench", "allocators"], "invalid choice: 'bench'"),  # studies left the wheel
    ],
)
def test_bad_arguments_say_what_is_allowed(argv: list[str], message: str) -> None:
    code, out, err = run(argv)
    assert code == 2 and message in err
    assert "'bogus', 'model'" not in err  # names only what the user typed
    assert "sim s" not in out + err  # refused before any simulation started


def test_record_writes_an_animation_and_a_frame(tmp_path: Path) -> None:
    pytest.importorskip("pygame", reason="recording needs the render extra")
    image = pytest.importorskip("PIL.Image", reason="recording needs the render extra")
    gif = tmp_path / "a.gif"
    argv = ["record", "--allocator", "random", "--minutes", "1", "--frame-s", "5"]
    code, out, _ = run([*argv, "--out", str(gif)])
    assert code == 0 and "12 frames" in out
    with image.open(gif) as im:
        assert im.n_frames == 12 and im.size[0] > 500
    png = tmp_path / "a.png"
    assert run([*argv, "--out", str(png)])[0] == 0
    with image.open(png) as im:
        assert im.format == "PNG"


def test_plots_from_saved_results(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib", reason="plots need the plot extra")
    softmax, rand = tmp_path / "softmax.json", tmp_path / "random.json"
    assert run(["trial", "--allocator", "softmax_tavc", *TINY, "--out", str(softmax)])[0] == 0
    assert run(["trial", "--allocator", "random", *TINY, "--out", str(rand)])[0] == 0
    for argv in (
        ["plot", "timeline", str(softmax), str(rand), "--from-h", "0.01"],
        ["plot", "q", str(softmax)],
        ["plot", "interference"],  # the committed benchmarks/results/interference.csv
    ):
        out = tmp_path / f"{argv[1]}.png"
        code, printed, err = run([*argv, "--out", str(out)])
        assert code == 0, err
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "wrote" in printed
    run_folder = ROOT / "benchmarks/results/marl/torchrl_mappo_dahl2004"
    code, printed, err = run(["plot", "curve", str(run_folder), "--out", str(tmp_path / "c.png")])
    assert code == 0 and (tmp_path / "c.png").read_bytes()[:4] == b"\x89PNG", err
    code, _, err = run(["plot", "curve", str(softmax), "--out", str(tmp_path / "x.png")])
    assert code == 2 and "a learning run's folder" in err
    code, _, err = run(["plot", "q", str(rand), "--out", str(tmp_path / "x.png")])
    assert code == 2 and "has no Q snapshots" in err
    code, _, err = run(["plot", "timeline", str(tmp_path / "missing.json")])
    assert code == 2 and "missing.json does not exist" in err
    code, _, err = run(
        ["plot", "timeline", str(rand), "--from-h", "5", "--out", str(tmp_path / "y.png")]
    )
    assert code == 2 and "is empty" in err


def test_version_and_python_m() -> None:
    from tavc_env import __version__

    code, out, _ = run(["--version"])
    assert code == 0 and out == f"tavc {__version__}\n"
    done = subprocess.run(
        [sys.executable, "-m", "tavc_agents", "--version"], capture_output=True, text=True
    )
    assert done.returncode == 0 and done.stdout == f"tavc {__version__}\n"


def test_version_does_not_import_the_env() -> None:
    """`tavc --version` imported the whole env (numpy, pymunk, numba) to read one string: 1.45 s.
    It reads the version from the source now, without importing `tavc_env`."""
    code = (
        "import sys\n"
        "from tavc_agents.cli import main\n"
        "try:\n"
        "    main(['--version'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('tavc_env', 'numpy', 'numba')))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "[]", done.stdout


@pytest.mark.parametrize(
    ("module", "distribution", "extra"),
    [
        ("torch", "torch", "marl"),
        ("benchmarl", "benchmarl", "benchmarl"),
        ("matplotlib.pyplot", "matplotlib", "plot"),
        ("PIL", "Pillow", "render"),
        ("ray", "ray", "ray"),
    ],
)
def test_a_missing_extra_is_one_line_naming_it(
    module: str, distribution: str, extra: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    import tavc_agents.cli as cli

    def needs(args: object) -> int:
        importlib.import_module(module)
        return 0

    monkeypatch.setitem(sys.modules, module, None)  # as if not installed: the import fails
    monkeypatch.setattr(cli, "cmd_trial", needs)
    code, out, err = run(["trial"])
    assert (code, out) == (2, "")
    assert err == (
        f"tavc trial: this needs {distribution}, which is not installed: "
        f"pip install 'tavc-env[{extra}]'\n"
    )


def test_pygame_missing_behind_the_renderers_own_error_is_named() -> None:
    from tavc_agents.cli import missing_extra

    try:
        try:
            raise ModuleNotFoundError("No module named 'pygame'", name="pygame")
        except ImportError as cause:
            raise ImportError("rendering needs pygame") from cause
    except ImportError as error:
        assert missing_extra(error) == (
            "this needs pygame, which is not installed: pip install 'tavc-env[render]'"
        )
    other = ModuleNotFoundError("No module named 'numpyy'", name="numpyy")
    assert missing_extra(other) is None  # not an extra: a bug, whose traceback is wanted


def test_outside_a_checkout_reference_results_are_not_assumed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What an installed wheel does where a checkout has benchmarks/results (simulated by
    CHECKOUT = None): it refuses to update them and says it has none to read."""
    import table1
    from tavc_agents.experiments import provenance, study

    assert Path(__file__).resolve().parents[2] == provenance.CHECKOUT  # the tests run in one
    monkeypatch.setattr(provenance, "CHECKOUT", None)
    monkeypatch.setattr(study, "CHECKOUT", None)
    with pytest.raises(ValueError, match=r"--update-reference is invalid here: .* allowed: --out"):
        table1.Settings(update_reference=True)
    code, _, err = run(["plot", "interference", "--out", str(tmp_path / "i.png")])
    assert code == 2 and "the committed one is part of a source checkout" in err
    code, _, err = run(["trial", "--allocator", "greedy", "--preset", "dahl2004_bays", *TINY])
    assert code == 2 and "no TAVC model of 'dahl2004_bays' ships with the package" in err


def test_allocator_choices_are_the_registrys_when_the_command_runs(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from tavc_agents.allocators.baselines import StayAllocator
    from tavc_agents.experiments import registry

    mine = registry.AllocatorRegistry(registry.BUILT_IN, group=None)
    monkeypatch.setattr(registry, "allocator_names", mine.names)
    monkeypatch.setattr(registry, "make_allocator", mine.make_allocator)
    assert run(["trial", "--allocator", "sticky_after_import", *TINY])[0] == 2  # not yet known
    mine.register("sticky_after_import", StayAllocator)  # after the CLI module was imported
    code, out, err = run(["trial", "--allocator", "sticky_after_import", *TINY])
    assert code == 0, err
    assert "sticky_after_import on dahl2004, seed 0" in out


def test_the_first_run_says_it_is_compiling(tmp_path: Path) -> None:
    """A first `tavc trial` in a fresh venv sat silent for a minute or more while numba compiled
    the controller. With an empty cache folder it now says so, on stderr, before any work."""
    import os

    code = (
        "import sys\n"
        "from tavc_env.engine.navigation import compiled_cache_ready\n"
        "from tavc_agents.cli import say_if_compiling\n"
        "print(compiled_cache_ready())\n"
        "say_if_compiling()\n"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}  # an empty cache: numba's first pick
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    ready = done.stdout.strip()
    if ready == "True":
        pytest.skip("numba found the in-tree cache; the message is tested below with it absent")
    assert ready == "False"
    assert "tavc: compiling the robots' controller with numba" in done.stderr


def test_no_compiling_message_once_the_cache_holds_the_controller(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from tavc_agents import cli
    from tavc_env import measurement

    monkeypatch.setattr(measurement, "compiled_cache_ready", lambda: True)
    cli.say_if_compiling()
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(measurement, "compiled_cache_ready", lambda: False)
    cli.say_if_compiling()
    assert "compiling the robots' controller" in capsys.readouterr().err
