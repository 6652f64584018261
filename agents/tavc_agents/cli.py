"""The `tavc` command: run a trial, record a video, reproduce the paper, run a benchmark.

    tavc trial --allocator softmax_tavc --measured-h 2            # one trial, progress bar, summary
    tavc trial --allocator greedy --preset three_circuits_three_classes
    tavc record --allocator random --minutes 5 --out arena.gif
    tavc reproduce                                          # the paper's Table 1 (study table1)
    tavc bench allocators --quick                           # any study in tavc_agents.studies
    tavc plot timeline trial.json --out timeline.png        # figures from saved results

`tavc <command> --help` explains each command. `reproduce` and `bench` run the package's studies
(`tavc_agents.studies`), the same code as the scripts in `benchmarks/`.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tavc_agents import studies

# The package (physics, numba, the studies) is imported only once a command runs, so that
# `tavc --help` answers at once (benchmarks/cli_startup.py measures it against `python -c pass`).
if TYPE_CHECKING:
    from tavc_agents.experiments.runner import TrialResult

NEEDS_MODEL = ("static", "greedy", "auction")
DESCRIPTION = (
    "Multi-robot task allocation in the prioritized transportation arena of Dahl, Mataric & "
    "Sukhatme (DARS 2004)."
)
EPILOG = (
    "Examples: tavc trial --allocator softmax_tavc --measured-h 2 | "
    "tavc record --minutes 5 --out arena.gif | tavc reproduce | tavc bench allocators --quick"
)
COMMANDS = {
    "trial": "run one trial and print a summary",
    "record": "record a trial to an animated GIF (or its last frame to a PNG)",
    "plot": "plot saved results (no rerun): timeline, q, interference, table1, curve",
    "reproduce": "reproduce the paper's Table 1 (the table1 study)",
    "bench": "run one of the package's studies (the benchmarks)",
}


MIN_FPS, MAX_FPS = 0.01, 100.0
"""The frame rates a GIF can hold: a frame's delay is 1 to 65535 hundredths of a second."""


def _allocator(args: argparse.Namespace) -> Any:
    from tavc_agents.experiments.registry import make_allocator
    from tavc_agents.model import missing_model, model_path, read_model
    from tavc_agents.studies.common import parse_key_values

    params = parse_key_values(args.param, "--param", "temperature=0.01")
    if args.allocator in NEEDS_MODEL and "model" not in params and "circuits" not in params:
        problem = missing_model(args.preset, args.model)
        if problem is not None:
            raise ValueError(
                f"allocator {args.allocator!r} needs the TAVC model of the arena: {problem}; "
                "allowed: --model PATH (a model.json written by tavc bench tavc_model)"
            )
        path = model_path(args.preset, args.model)
        try:
            params["model"] = read_model(path)
        except ValueError as error:
            raise ValueError(
                f"--model {path} could not be read ({error}); allowed: a model.json written by "
                "the tavc_model study (tavc bench tavc_model)"
            ) from None
    return make_allocator(args.allocator, **params)


def _trial_options(parser: argparse.ArgumentParser) -> None:
    from tavc_agents.experiments.registry import allocator_names
    from tavc_env import PRESETS

    parser.add_argument("--preset", default="dahl2004", choices=sorted(PRESETS))
    parser.add_argument(  # the names now, with plugins' (tavc.allocators entry points)
        "--allocator",
        default="softmax_tavc",
        choices=allocator_names(),
        help="default: softmax_tavc",
    )
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="allocator parameter, e.g. --param temperature=0.01 --param init=paper (repeatable)",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="arena override, e.g. --set source_service_s=15 (repeatable)",
    )
    parser.add_argument(
        "--model",
        type=Path,
        default=None,
        help=f"model.json for {', '.join(NEEDS_MODEL)} (default: the one the package ships for "
        "the preset)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="the trial's seed: the arena's and every robot's generator come from it (default: 0)",
    )


def say_if_compiling() -> None:
    """Say, on stderr, that the robots' controller is being compiled when numba's cache does not
    hold it (the first run in a fresh environment sat silent for a minute or more)."""
    from tavc_env.engine.navigation import compiled_cache_ready

    if compiled_cache_ready() is False:
        print(
            "tavc: compiling the robots' controller with numba (the first run in this "
            "environment only: about 7 CPU s, a minute or more on a busy machine; cached after)",
            file=sys.stderr,
            flush=True,
        )


def cmd_trial(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from tavc_agents.experiments.runner import run_trial
    from tavc_agents.studies.common import arena_overrides
    from tavc_env import make_config

    allocator = _allocator(args)  # bad parameters and arenas are refused before the run starts
    overrides = arena_overrides(args.set)
    make_config(args.preset, **overrides)
    total = args.convergence_h + args.measured_h
    say_if_compiling()
    bars: list[Any] = []  # made at the first report, so a trial refused as it starts shows none
    done = [0]

    def progress(t: float) -> None:
        if not bars:
            bars.append(
                tqdm(total=round(total * 3600), unit="sim s", dynamic_ncols=True, file=sys.stderr)
            )
        bars[0].update(round(t) - done[0])
        done[0] = round(t)

    try:
        result = run_trial(
            allocator,
            seed=args.seed,
            convergence_s=args.convergence_h * 3600.0,
            measured_s=args.measured_h * 3600.0,
            progress=progress,
            preset=args.preset,
            arena=overrides,
        )
    finally:
        for bar in bars:
            bar.close()
    print(summary(result, args.allocator))
    if args.out is not None:
        result.save(args.out)
        print(f"wrote {args.out}")
    return 0


def summary(result: TrialResult, allocator: str) -> str:
    """A trial's measured period as a small table."""
    import numpy as np

    from tavc_agents.analysis import allocation
    from tavc_env import metrics

    t0, t1 = result.measured_window
    perf = allocation.delivered_performance(result, t0, t1)
    shares = [
        metrics.time_share(result.initial_circuits, result.changes, c, t0, t1)
        for c in range(len(result.values))
    ]
    classes = sorted(set(result.speed_classes), key=result.speed_classes.index)
    lines = [
        f"{allocator} on {result.env_kwargs.get('preset', 'dahl2004')}, seed {result.seed}: "
        f"measured {(t1 - t0) / 3600:g} h after {t0 / 3600:g} h",
        f"  delivered value per robot per 10 s: {perf:.4f}",
        "  circuit switches per robot per hour: "
        f"{allocation.switches_per_robot_h(result, t0, t1):.2f}",
        f"  share of time on each circuit (circuit values {[round(w) for w in result.values]}):",
    ]
    for cls in classes:
        members = [i for i, c in enumerate(result.speed_classes) if c == cls]
        row = [float(np.mean([s[i] for i in members])) for s in shares]
        lines.append(f"    {cls:>8} robots ({len(members)}): " + "  ".join(f"{x:.2f}" for x in row))
    jams = f"{result.jams} ({result.jammed_s / 60:.0f} min jammed)" if result.jams else "none"
    lines.append(f"  wall time {result.wall_s:.1f} s; escapes {result.escapes}; jams {jams}")
    return "\n".join(lines)


def cmd_record(args: argparse.Namespace) -> int:
    from PIL import Image  # the render extra (`missing_extra` names it if absent)

    kind = args.out.suffix.lower()
    if kind not in (".gif", ".png"):
        raise ValueError(
            f"--out {args.out} is invalid; allowed: a .gif (animation) or .png (last frame) file"
        )
    from tavc_agents.experiments.runner import run_trial
    from tavc_agents.studies.common import arena_overrides
    from tavc_env import EnvOptions

    frames: list[Any] = []
    say_if_compiling()

    def grab(env: Any) -> None:
        frames.append(Image.fromarray(env.render()))

    run_trial(
        _allocator(args),
        seed=args.seed,
        convergence_s=0.0,
        measured_s=args.minutes * 60.0,
        on_step=grab,
        preset=args.preset,
        arena=arena_overrides(args.set),
        options=EnvOptions(render_mode="rgb_array", decision_interval_s=args.frame_s),
    )
    if kind == ".png":
        frames[-1].save(args.out)
        print(f"wrote {args.out}: the arena after {args.minutes:g} simulated minutes")
        return 0
    frames[0].save(
        args.out,
        save_all=True,
        append_images=frames[1:],
        duration=round(1000 / args.fps),
        loop=0,
        optimize=True,
    )
    print(
        f"wrote {args.out}: {len(frames)} frames, {args.frame_s:g} simulated s each, "
        f"at {args.fps:g} frames per second"
    )
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    from tavc_agents.analysis import plots
    from tavc_agents.experiments.provenance import CHECKOUT
    from tavc_agents.experiments.runner import TrialResult
    from tavc_agents.experiments.study import RESULTS_DIR

    if args.what == "interference":
        if args.source is None and CHECKOUT is None:
            raise ValueError(
                "plot interference needs an interference.csv: the committed one is part of a "
                "source checkout, and this package is installed; allowed: a path to one written "
                "by tavc bench interference"
            )
        source = args.source or RESULTS_DIR / "interference.csv"
        plots.interference_curve(_existing(source, "an interference.csv"), args.out)
    elif args.what == "table1":
        from tavc_agents.studies import table1

        table1.draw_figure(Path(args.source), args.figure, args.out)
    elif args.what == "curve":
        plots.redraw_learning_curve(Path(args.source), args.out)
    else:
        trials = {}
        for source in args.source_list:
            result = TrialResult.load(source)
            trials[result.label or Path(source).stem] = result
        if args.what == "timeline":
            plots.allocation_timeline(trials, args.out, args.from_h, args.to_h)
        else:
            if len(trials) != 1:
                raise ValueError(f"q takes one trial file, given {len(trials)}; allowed: one")
            plots.q_trajectories(next(iter(trials.values())), args.out)
    print(f"wrote {args.out}")
    return 0


def _existing(path: str | Path, allowed: str, *, folder: bool = False) -> Path:
    """`path`, if it is an existing file (or folder, if `folder`); a ValueError saying what it
    is and what is `allowed` otherwise (checked when the command line is read)."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"{path} does not exist; allowed: {allowed}")
    if path.is_dir() != folder:
        raise ValueError(
            f"{path} is {'not a folder' if folder else 'a folder'}; allowed: {allowed}"
        )
    return path


def _run_study(name: str, argv: Sequence[str], prog: str) -> int:
    """Run study `name` with command-line arguments `argv`, as `benchmarks/<name>.py` does."""
    try:  # importing the study takes a second or two: Ctrl-C then is one line too
        from tavc_agents.experiments.study import run_study

        module = studies.load(name)
    except KeyboardInterrupt:
        print(
            f"\n{prog}: interrupted before the study started; nothing was written.", file=sys.stderr
        )
        return 130
    return run_study(module, argv, module.__doc__ or name, prog)


def version() -> str:
    """The package's version, read from `tavc_env/__init__.py` without importing `tavc_env`
    (importing it loads numpy, pymunk, numba and the env: about a second, for one string); the
    installed metadata if the source cannot be read."""
    import importlib.util
    import re

    spec = importlib.util.find_spec("tavc_env")  # finds the package; does not run it
    if spec is not None and spec.origin is not None:
        try:
            text = Path(spec.origin).read_text(encoding="utf-8")
        except OSError:  # pragma: no cover - a zipped or unreadable install
            text = ""
        found = re.search(r'^__version__ = "([^"]+)"$', text, re.MULTILINE)
        if found:
            return found.group(1)
    from importlib.metadata import version as installed  # pragma: no cover

    return installed("tavc-env")  # pragma: no cover


class _Version(argparse.Action):
    """`tavc --version`: the package's version, read without importing the env."""

    def __call__(self, parser: argparse.ArgumentParser, *args: Any, **kwargs: Any) -> None:
        print(f"tavc {version()}")
        parser.exit()


def _top_parser() -> argparse.ArgumentParser:
    top = argparse.ArgumentParser(prog="tavc", description=DESCRIPTION, epilog=EPILOG)
    top.add_argument("--version", action=_Version, nargs=0, help="show the version and exit")
    return top


EXTRAS = {
    "scipy": ("scipy", "bench"),
    "matplotlib": ("matplotlib", "plot"),
    "pygame": ("pygame", "render"),
    "PIL": ("Pillow", "render"),
    "ray": ("ray", "ray"),
}
"""Optional dependencies by top-level module: the distribution, and the extra of `tavc-env` that
installs it."""


def missing_extra(error: ImportError) -> str | None:
    """The line that names the extra to install, if `error` (or what caused it) is an optional
    dependency that is not installed; None for any other import error (a bug, not a setup)."""
    cause: BaseException | None = error
    while cause is not None:
        module = (getattr(cause, "name", None) or "").partition(".")[0]
        if isinstance(cause, ModuleNotFoundError) and module in EXTRAS:
            distribution, extra = EXTRAS[module]
            return (
                f"this needs {distribution}, which is not installed: "
                f"pip install 'tavc-env[{extra}]'"
            )
        cause = cause.__cause__ or cause.__context__
    return None


def light_parser() -> argparse.ArgumentParser:
    """The top level only (commands and their one-line help): what `tavc --help` shows, without
    importing the package."""
    top = _top_parser()
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, text in COMMANDS.items():
        sub.add_parser(name, help=text, add_help=False)
    return top


def parser() -> argparse.ArgumentParser:
    from tavc_agents.experiments.registry import BUILT_IN

    top = _top_parser()
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")

    trial = sub.add_parser(
        "trial",
        help=COMMANDS["trial"],
        description="Run one trial: a convergence period, then a measured period whose delivered "
        "value, switches and time shares are printed. Team allocators "
        f"({', '.join(a.name for a in BUILT_IN if a.team)}, and any plugin's declared as one) "
        "coordinate the robots; the others are per robot.",
    )
    _trial_options(trial)
    trial.add_argument(
        "--convergence-h",
        type=float,
        default=15.0,
        help="learning (convergence) period before it, hours (default 15, the paper's)",
    )
    trial.add_argument(
        "--measured-h", type=float, default=5.0, help="measured period, hours (default 5)"
    )
    trial.add_argument("--out", type=Path, default=None, help="save the full result as JSON")
    trial.set_defaults(run=cmd_trial)

    record = sub.add_parser(
        "record",
        help=COMMANDS["record"],
        description="Run a trial from the start and save one rendered frame every --frame-s "
        "simulated seconds as an animated GIF, or the last frame as a PNG (needs the render "
        "extra: pygame and Pillow).",
    )
    _trial_options(record)
    record.add_argument("--minutes", type=float, default=5.0, help="simulated minutes (default 5)")
    record.add_argument("--frame-s", type=float, default=2.0, help="simulated s per frame (2)")
    record.add_argument("--fps", type=float, default=15.0, help="frames per second of the GIF")
    record.add_argument(
        "--out", type=Path, default=Path("arena.gif"), help="the .gif or .png to write"
    )
    record.set_defaults(run=cmd_record)

    plot = sub.add_parser(
        "plot",
        help=COMMANDS["plot"],
        description="Draw a figure from saved results. timeline: which circuit each robot served "
        "over time, one panel per trial file (from `tavc trial --out` or a benchmark's saved "
        "trials); q: the learners' Q(high) - Q(other) over time, fast against slow; interference: "
        "the interference curve t(n) from benchmarks/results/interference.csv; table1: one of Table "
        "1's figures drawn from a table1 output folder's saved trials; curve: a deep learner's "
        "learning curve from its run folder's curve.csv (docs/examples/*.py --out).",
    )
    plot.add_argument("what", choices=["timeline", "q", "interference", "table1", "curve"])
    plot.add_argument(
        "source_list",
        nargs="*",
        metavar="FILE",
        help="trial JSON file(s) (timeline, q), interference.csv (default: the committed one), "
        "a table1 output folder (table1), or a learning run's folder (curve)",
    )
    plot.add_argument("--from-h", type=float, default=None, help="timeline: start (hours)")
    plot.add_argument("--to-h", type=float, default=None, help="timeline: end (hours)")
    plot.add_argument(
        "--figure",
        choices=["figure2.png", "performance.png"],
        default="figure2.png",
        help="table1: which figure (default: figure2.png, the paper's Figure 2)",
    )
    plot.add_argument(
        "--out", type=Path, default=Path("plot.png"), help="the PNG to write (and nothing else)"
    )
    plot.set_defaults(run=cmd_plot)

    reproduce = sub.add_parser(
        "reproduce",
        help=COMMANDS["reproduce"],
        description="Run the table1 study with the arguments that follow.",
        add_help=False,  # `tavc reproduce --help` is the study's own help, every option listed
    )
    reproduce.add_argument("script_args", nargs=argparse.REMAINDER)
    reproduce.set_defaults(
        run=lambda a: _run_study("table1", _strip(a.script_args), "tavc reproduce")
    )

    bench = sub.add_parser(
        "bench",
        help=COMMANDS["bench"],
        description="Run study NAME with the arguments that follow (its options: "
        f"tavc bench NAME -- --help); NAME is one of: {', '.join(sorted(studies.STUDIES))}.",
    )
    bench.add_argument("name", help="the study's name, e.g. allocators")
    bench.add_argument("script_args", nargs=argparse.REMAINDER)
    bench.set_defaults(
        run=lambda a: _run_study(a.name, _strip(a.script_args), f"tavc bench {a.name}")
    )
    for command in sub.choices.values():  # its errors show its own usage line
        command.set_defaults(command_parser=command)
    return top


def _check_arguments(args: argparse.Namespace) -> None:
    """Refuse (a ValueError naming the option, its value and what is allowed) what the parser
    let through but no command can use: hours, minutes, rates and seeds out of range, the plot's
    window, and input files that are not there or are folders; before any work starts."""
    from tavc_agents.experiments.limits import (
        MAX_HOURS,
        SEEDS,
        hours_allowed,
        valid_hours,
        valid_seed,
    )

    hours = [("measured_h", False), ("convergence_h", True), ("from_h", True), ("to_h", True)]
    for name, zero in hours:
        value = getattr(args, name, None)
        if value is not None and not valid_hours(value, zero=zero):
            raise ValueError(
                f"--{name.replace('_', '-')} = {value}; allowed: {hours_allowed(zero=zero)}"
            )
    minutes = getattr(args, "minutes", None)
    if minutes is not None and not valid_hours(minutes / 60, zero=False):
        raise ValueError(
            f"--minutes = {minutes}; allowed: a finite number > 0 and <= {MAX_HOURS * 60:g} "
            "(simulated minutes)"
        )
    frame_s = getattr(args, "frame_s", None)
    if frame_s is not None and not (math.isfinite(frame_s) and frame_s > 0):
        raise ValueError(f"--frame-s = {frame_s}; allowed: a finite number > 0")
    fps = getattr(args, "fps", None)
    if fps is not None and not (math.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
        raise ValueError(
            f"--fps = {fps}; allowed: a number in [{MIN_FPS:g}, {MAX_FPS:g}] (a GIF holds each "
            "frame's delay in hundredths of a second, at most 655.35 s)"
        )
    seed = getattr(args, "seed", None)
    if seed is not None and not valid_seed(seed):
        raise ValueError(f"--seed = {seed}; allowed: {SEEDS}")
    if getattr(args, "what", None) is None:
        return
    args.source = args.source_list[0] if args.source_list else None
    if args.what != "interference" and not args.source_list:
        raise ValueError(
            f"plot {args.what} needs its input; allowed: trial JSON file(s) for timeline and "
            "q, a table1 output folder for table1, a learning run's folder for curve"
        )
    if args.from_h is not None and args.to_h is not None and not args.from_h < args.to_h:
        raise ValueError(
            f"--from-h = {args.from_h} and --to-h = {args.to_h} are invalid together; allowed: "
            "--from-h below --to-h"
        )
    if args.what == "table1":
        _existing(args.source, "an output folder of the table1 study", folder=True)
    elif args.what == "curve":
        _existing(args.source, "a learning run's folder (docs/examples/*.py --out)", folder=True)
    elif args.what in ("timeline", "q"):
        for source in args.source_list:
            _existing(source, "a trial JSON file (tavc trial --out, or a study's saved trial)")


def _strip(args: Sequence[str]) -> list[str]:
    return list(args[1:]) if args and args[0] == "--" else list(args)


def main(argv: Sequence[str] | None = None) -> int:
    given = list(sys.argv[1:] if argv is None else argv)
    if not given or given[0] in ("-h", "--help", "--version") or given[0] not in COMMANDS:
        light_parser().parse_args(given)  # help, or the error for a missing or unknown command
    top = parser()
    # `tavc reproduce --quick` and `tavc bench NAME --trials 3`: the study's own options follow
    # the command (with or without a `--` first); the study's parser checks them
    args, extra = top.parse_known_args(argv)
    refuse = getattr(args, "command_parser", top).error
    if extra and not hasattr(args, "script_args"):
        refuse(f"unrecognized arguments: {' '.join(extra)}")
    if hasattr(args, "script_args"):
        args.script_args = [*extra, *args.script_args]
    if getattr(args, "name", None) is not None and args.name not in studies.STUDIES:
        refuse(f"study {args.name!r} is unknown; allowed: {sorted(studies.STUDIES)}")
    try:
        _check_arguments(args)
    except ValueError as error:
        refuse(str(error))
    try:
        if getattr(args, "out", None) is not None:
            from tavc_agents.experiments.files import check_writable

            check_writable(args.out)  # before any simulation, not after it
        code: int = args.run(args)
    except ValueError as error:  # also a plugin that does not load (registry.PluginError)
        refuse(str(error))
    except ImportError as error:
        line = missing_extra(error)
        if line is None:
            raise
        print(f"tavc {args.command}: {line}", file=sys.stderr)
        return 2
    return code


if __name__ == "__main__":
    sys.exit(main())
