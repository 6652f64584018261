"""The `tavc` command: run a trial, record a video, plot saved results.

    tavc trial --allocator softmax_tavc --measured-h 2            # one trial, progress bar, summary
    tavc trial --allocator greedy --preset three_circuits_three_classes
    tavc trial --scenario bad_start                         # a scenario of the suite
    tavc record --allocator random --minutes 5 --out arena.gif
    tavc plot timeline trial.json --out timeline.png        # figures from saved results

`tavc <command> --help` explains each command. The research studies (the paper's Table 1 among
them) are programs of the source repository, `python benchmarks/<study>.py`, not commands of the
installed package.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

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
    "tavc record --minutes 5 --out arena.gif | tavc plot timeline trial.json | "
    "tavc evaluate --allocator greedy --scenario passing"
)
COMMANDS = {
    "trial": "run one trial and print a summary",
    "record": "record a trial to an animated GIF (or its last frame to a PNG)",
    "plot": "plot saved results (no rerun): timeline, q, interference, curve",
    "evaluate": "score an agent on the scenario suite's evaluation protocol (IQM with its interval)",
}


MIN_FPS, MAX_FPS = 0.01, 100.0
"""The frame rates a GIF can hold: a frame's delay is 1 to 65535 hundredths of a second."""


def _arena(args: argparse.Namespace) -> Any:
    """The arena the command line names: `--scenario` or `--preset` (default dahl2004), with the
    `--set` overrides, resolved (and any clash refused) by `tavc_env.resolve_arena`."""
    from tavc_agents.experiments.command_line import parse_key_values
    from tavc_env import resolve_arena

    overrides = parse_key_values(args.set, "--set", "source_service_s=15")
    choices = sorted(k for k in overrides if k in ("scenario", "preset", "config"))
    if choices:
        raise ValueError(
            f"--set {choices[0]}={overrides[choices[0]]} is invalid; allowed: arena overrides "
            "(say which arena with --preset or --scenario)"
        )
    return resolve_arena({"scenario": args.scenario, "preset": args.preset, **overrides})


def _allocator(args: argparse.Namespace, arena: Any) -> Any:
    from tavc_agents.experiments.command_line import parse_key_values
    from tavc_agents.experiments.registry import make_allocator
    from tavc_agents.model import missing_model, model_path, read_model

    params = parse_key_values(args.param, "--param", "temperature=0.01")
    if args.allocator in NEEDS_MODEL and "model" not in params and "circuits" not in params:
        # a scenario's reference model, or the preset's
        preset = arena.scenario.model if arena.scenario is not None else arena.preset
        problem = missing_model(preset or "dahl2004", args.model)
        if problem is not None:
            raise ValueError(
                f"allocator {args.allocator!r} needs the TAVC model of the arena: {problem}; "
                "allowed: --model PATH (a model.json written by python benchmarks/tavc_model.py)"
            )
        path = model_path(preset or "dahl2004", args.model)
        try:
            params["model"] = read_model(path)
        except ValueError as error:
            raise ValueError(
                f"--model {path} could not be read ({error}); allowed: a model.json written by "
                "the tavc_model study (python benchmarks/tavc_model.py)"
            ) from None
    return make_allocator(args.allocator, **params)


def _trial_options(parser: argparse.ArgumentParser) -> None:
    from tavc_agents.experiments.registry import allocator_names
    from tavc_env import PRESETS, SCENARIOS

    parser.add_argument(
        "--preset", default=None, choices=sorted(PRESETS), help="the arena (default: dahl2004)"
    )
    parser.add_argument(
        "--scenario",
        default=None,
        metavar="NAME",
        help=f"a scenario of the suite instead ({', '.join(sorted(SCENARIOS))}, or its id "
        "tavc/<name>-v<version>): its arena and its priority shifts",
    )
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
        help="arena override of the preset, e.g. --set source_service_s=15 (repeatable)",
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
    from tavc_env.measurement import compiled_cache_ready

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

    arena = _arena(args)  # bad arenas and parameters are refused before the run starts
    allocator = _allocator(args, arena)
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
            arena=arena,
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
        f"{allocator} on {_arena_name(result.env_kwargs)}, seed {result.seed}: "
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


def _arena_name(env_kwargs: dict[str, Any]) -> str:
    """How a trial's record names its arena: its scenario, or its preset (default dahl2004)."""
    if "scenario" in env_kwargs:
        return f"scenario {env_kwargs['scenario']}"
    if "config" in env_kwargs:
        return "a given ArenaConfig"
    return str(env_kwargs.get("preset", "dahl2004"))


def cmd_record(args: argparse.Namespace) -> int:
    from PIL import Image  # the render extra (`missing_extra` names it if absent)

    kind = args.out.suffix.lower()
    if kind not in (".gif", ".png"):
        raise ValueError(
            f"--out {args.out} is invalid; allowed: a .gif (animation) or .png (last frame) file"
        )
    from tavc_agents.experiments.runner import run_trial
    from tavc_env import EnvOptions

    frames: list[Any] = []
    say_if_compiling()

    def grab(env: Any) -> None:
        frames.append(Image.fromarray(env.render()))

    arena = _arena(args)
    run_trial(
        _allocator(args, arena),
        seed=args.seed,
        convergence_s=0.0,
        measured_s=args.minutes * 60.0,
        on_step=grab,
        arena=arena,
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


def _imported(spec: str) -> Any:
    """The object `spec` names, `FILE.py:NAME` or `MODULE:NAME` (a policy of your own), loaded;
    a ValueError naming what is wrong otherwise."""
    import importlib
    import importlib.util

    where, sep, attr = spec.rpartition(":")
    if not sep or not where or not attr:
        raise ValueError(
            f"--policy {spec!r} is invalid; allowed: FILE.py:NAME or MODULE:NAME, e.g. "
            "my_agent.py:policy"
        )
    try:
        if where.endswith(".py"):
            path = Path(where)
            if not path.is_file():
                raise ValueError(f"--policy {spec!r}: {where} is not a file")
            loaded = importlib.util.spec_from_file_location(path.stem, path)
            assert loaded is not None and loaded.loader is not None
            module = importlib.util.module_from_spec(loaded)
            sys.modules[path.stem] = module  # (dataclasses and pickling look it up)
            loaded.loader.exec_module(module)
        else:
            module = importlib.import_module(where)
        found = getattr(module, attr)
    except (ImportError, AttributeError, SyntaxError) as error:
        raise ValueError(f"--policy {spec!r} could not be loaded: {error}") from error
    if not callable(found):
        raise ValueError(f"--policy {spec!r} is a {type(found).__name__}; allowed: a callable")
    return found


def cmd_evaluate(args: argparse.Namespace) -> int:
    from tavc_agents.evaluation import SUITE, evaluate
    from tavc_agents.experiments.command_line import parse_key_values

    given = [x for x in (args.allocator, args.network, args.policy) if x is not None]
    if len(given) != 1:
        raise ValueError(
            f"{len(given)} agents given; allowed: exactly one of --allocator NAME, --network PATH "
            "or --policy MODULE:NAME"
        )
    if args.network is not None:
        agent: Any = Path(args.network)
    elif args.policy is not None:
        agent = _imported(args.policy)
    else:
        agent = args.allocator
    params = parse_key_values(args.param, "--param", "temperature=0.01")
    scenarios = args.scenario or [SUITE]
    result = evaluate(
        agent,
        SUITE if SUITE in scenarios else scenarios,
        seeds=args.seeds,
        episode_h=args.episode_h,
        params=params,
        readout=args.readout,
        observation_mode=args.observation,
        workers=args.workers,
        name=args.name,
        progress=True,
    )
    print(
        f"{result.name} ({result.kind}, read out {result.readout}): normalised score, 0 = random "
        "allocation, 1 = the model optimum; IQM over evaluation episodes [95 % bootstrap CI]"
    )
    print(result.table())
    if args.out is not None:
        print(
            f"wrote {result.save(args.out)} (the leaderboard row: benchmarks/leaderboard.py --rows)"
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
                "by python benchmarks/interference.py"
            )
        source = args.source or RESULTS_DIR / "interference.csv"
        plots.interference_curve(_existing(source, "an interference.csv"), args.out)
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
    "matplotlib": ("matplotlib", "plot"),
    "pygame": ("pygame", "render"),
    "PIL": ("Pillow", "render"),
    "ray": ("ray", "ray"),
    "torch": ("torch", "marl"),
    "torchrl": ("torchrl", "marl"),
    "tensordict": ("tensordict", "marl"),
    "stable_baselines3": ("stable-baselines3", "marl"),
    "sb3_contrib": ("sb3-contrib", "marl"),
    "supersuit": ("supersuit", "marl"),
    "tianshou": ("tianshou", "marl"),
    "benchmarl": ("benchmarl", "benchmarl"),
    "yaml": ("pyyaml", "benchmarl"),
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

    ev = sub.add_parser(
        "evaluate",
        help=COMMANDS["evaluate"],
        description="Run an agent on the evaluation episodes of one or more scenarios (each "
        "episode s is env.reset(seed=s) on the scenario's env, of the scenario's length) and print "
        "each scenario's normalised score: the interquartile mean with a 95 % percentile bootstrap "
        "interval, and the suite's (stratified by scenario). --out writes the leaderboard row.",
    )
    ev.add_argument("--allocator", default=None, help="a registered allocator's name (plugins too)")
    ev.add_argument("--network", default=None, help="a saved network's .npz (Mlp.save)")
    ev.add_argument(
        "--policy",
        default=None,
        help="FILE.py:NAME or MODULE:NAME of a callable: policy(observations, infos) -> "
        "actions, or a Policy factory taking an agent's name",
    )
    ev.add_argument(
        "--param", action="append", default=[], metavar="KEY=VALUE", help="allocator parameter"
    )
    ev.add_argument(
        "--scenario",
        action="append",
        default=None,
        metavar="NAME",
        help="a scenario (repeat for several; default: the whole suite, also 'suite')",
    )
    ev.add_argument("--seeds", type=int, default=None, help="the first N evaluation seeds (all)")
    ev.add_argument("--episode-h", type=float, default=None, help="shorter episodes, hours")
    ev.add_argument(
        "--readout",
        choices=["sampled", "greedy"],
        default="sampled",
        help="a network: sampled, as a stochastic policy acts (default), or greedy",
    )
    ev.add_argument(
        "--observation",
        choices=["paper", "paper_id", "rich"],
        default=None,
        help="the env's observation (default: the env's; rich adds the circuits' values)",
    )
    ev.add_argument("--workers", type=int, default=1, help="processes (allocators, networks)")
    ev.add_argument("--name", default=None, help="the row's name (default: the agent's)")
    ev.add_argument("--out", type=Path, default=None, help="write the leaderboard row (JSON)")
    ev.set_defaults(run=cmd_evaluate)

    plot = sub.add_parser(
        "plot",
        help=COMMANDS["plot"],
        description="Draw a figure from saved results. timeline: which circuit each robot served "
        "over time, one panel per trial file (from `tavc trial --out` or a benchmark's saved "
        "trials); q: the learners' Q(high) - Q(other) over time, fast against slow; interference: "
        "the interference curve t(n) from benchmarks/results/interference.csv; curve: a deep learner's "
        "learning curve from its run folder's curve.csv (docs/examples/*.py --out).",
    )
    plot.add_argument("what", choices=["timeline", "q", "interference", "curve"])
    plot.add_argument(
        "source_list",
        nargs="*",
        metavar="FILE",
        help="trial JSON file(s) (timeline, q), interference.csv (default: the committed one), "
        "or a learning run's folder (curve)",
    )
    plot.add_argument("--from-h", type=float, default=None, help="timeline: start (hours)")
    plot.add_argument("--to-h", type=float, default=None, help="timeline: end (hours)")
    plot.add_argument(
        "--out", type=Path, default=Path("plot.png"), help="the PNG to write (and nothing else)"
    )
    plot.set_defaults(run=cmd_plot)

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
            "q, a learning run's folder for curve"
        )
    if args.from_h is not None and args.to_h is not None and not args.from_h < args.to_h:
        raise ValueError(
            f"--from-h = {args.from_h} and --to-h = {args.to_h} are invalid together; allowed: "
            "--from-h below --to-h"
        )
    if args.what == "curve":
        _existing(args.source, "a learning run's folder (docs/examples/*.py --out)", folder=True)
    elif args.what in ("timeline", "q"):
        for source in args.source_list:
            _existing(source, "a trial JSON file (tavc trial --out, or a study's saved trial)")


def main(argv: Sequence[str] | None = None) -> int:
    given = list(sys.argv[1:] if argv is None else argv)
    if not given or given[0] in ("-h", "--help", "--version") or given[0] not in COMMANDS:
        light_parser().parse_args(given)  # help, or the error for a missing or unknown command
    top = parser()
    args, extra = top.parse_known_args(argv)
    refuse = getattr(args, "command_parser", top).error
    if extra:
        refuse(f"unrecognized arguments: {' '.join(extra)}")
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
