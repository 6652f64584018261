"""The `tavc` command: run a trial, record a video, reproduce the paper, run a benchmark.

    tavc trial --allocator softmax_tavc --hours 2            # one trial, progress bar, summary
    tavc trial --allocator greedy --preset three_circuits_three_classes
    tavc record --allocator random --minutes 5 --out arena.gif
    tavc reproduce                                          # benchmarks/table1.py (the paper)
    tavc bench allocators --quick                           # any script in benchmarks/
    tavc plot timeline trial.json --out timeline.png        # figures from saved results

`tavc <command> --help` explains each command. Benchmark scripts live in the source checkout
(`benchmarks/`), so `reproduce` and `bench` need the package installed from it (`pip install -e .`).
"""

from __future__ import annotations

import argparse
import json
import runpy
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.registry import ALLOCATORS, TEAMS, make_allocator
from agents.experiments.runner import TrialResult, run_trial
from tavc_env import PRESETS, metrics

REPO = Path(__file__).resolve().parent.parent
BENCHMARKS = REPO / "benchmarks"
NEEDS_MODEL = ("static", "greedy", "auction")


def parse_key_values(items: Sequence[str], option: str, example: str) -> dict[str, Any]:
    """`KEY=VALUE` items (as given to `option`) as a dict: values that parse as JSON (numbers,
    true/false, lists) are used as such, anything else as a string; whoever receives them then
    names any key or value it does not accept. A ValueError shows `example` for a malformed one."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise ValueError(f"{option} {item!r} is invalid; allowed: KEY=VALUE, e.g. {example}")
        try:
            out[key] = json.loads(text)
        except json.JSONDecodeError:
            out[key] = text
    return out


def _allocator(args: argparse.Namespace) -> Any:
    params = parse_key_values(args.param, "--param", "temperature=0.01")
    if args.allocator in NEEDS_MODEL and "model" not in params and "circuits" not in params:
        path = args.model or BENCHMARKS / "results" / "tavc_model" / args.preset / "model.json"
        if not Path(path).exists():
            raise ValueError(
                f"allocator {args.allocator!r} needs the TAVC model of the arena, and {path} does "
                f"not exist; allowed: --model PATH, or make it with: tavc bench tavc_model "
                f"--preset {args.preset}"
            )
        try:
            params["model"] = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as error:
            raise ValueError(
                f"--model {path} could not be read ({error}); allowed: a model.json written by "
                "benchmarks/tavc_model.py"
            ) from None
    return make_allocator(args.allocator, **params)


def _trial_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", default="dahl2004", choices=sorted(PRESETS))
    parser.add_argument(
        "--allocator", default="softmax_tavc", choices=ALLOCATORS, help="default: softmax_tavc"
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
        help=f"model.json for {', '.join(NEEDS_MODEL)} (default: the committed one of the preset)",
    )
    parser.add_argument("--seed", type=int, default=0)


def cmd_trial(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    total = args.convergence_h + args.hours
    bar = tqdm(total=round(total * 3600), unit="sim s", dynamic_ncols=True, file=sys.stdout)
    done = [0]

    def progress(t: float) -> None:
        bar.update(round(t) - done[0])
        done[0] = round(t)

    try:
        result = run_trial(
            _allocator(args),
            seed=args.seed,
            convergence_s=args.convergence_h * 3600.0,
            measured_s=args.hours * 3600.0,
            progress=progress,
            preset=args.preset,
            **parse_key_values(args.set, "--set", "source_service_s=15"),
        )
    finally:
        bar.close()
    print(summary(result, args.allocator))
    if args.out is not None:
        result.save(args.out)
        print(f"wrote {args.out}")
    return 0


def summary(result: TrialResult, allocator: str) -> str:
    """A trial's measured period as a small table."""
    t0, t1 = result.measured_window
    n = len(result.agents)
    perf = metrics.value_rate(
        result.delivery_time_s, result.delivery_circuit, result.values, n, t0, t1
    )
    shares = [
        metrics.time_share(result.initial_circuits, result.changes, c, t0, t1)
        for c in range(len(result.values))
    ]
    classes = sorted(set(result.speed_classes), key=result.speed_classes.index)
    lines = [
        f"{allocator} on {result.env_kwargs.get('preset', 'dahl2004')}, seed {result.seed}: "
        f"measured {(t1 - t0) / 3600:g} h after {t0 / 3600:g} h",
        f"  delivered value per robot per 10 s: {perf:.4f}",
        f"  circuit switches per robot per hour: "
        f"{sum(1 for t, _, _ in result.changes if t0 <= t < t1) / n / ((t1 - t0) / 3600):.2f}",
        f"  share of time on each circuit (circuit values {[round(w) for w in result.values]}):",
    ]
    for cls in classes:
        members = [i for i, c in enumerate(result.speed_classes) if c == cls]
        row = [float(np.mean([s[i] for i in members])) for s in shares]
        lines.append(f"    {cls:>8} robots ({len(members)}): " + "  ".join(f"{x:.2f}" for x in row))
    lines.append(f"  wall time {result.wall_s:.1f} s; escapes {result.escapes}")
    return "\n".join(lines)


def cmd_record(args: argparse.Namespace) -> int:
    try:
        from PIL import Image
    except ImportError as error:
        raise ImportError(
            "recording needs Pillow and pygame: pip install 'tavc-env[render]'"
        ) from error
    kind = args.out.suffix.lower()
    if kind not in (".gif", ".png"):
        raise ValueError(
            f"--out {args.out} is invalid; allowed: a .gif (animation) or .png (last frame) file"
        )
    frames: list[Any] = []

    def grab(env: Any) -> None:
        frames.append(Image.fromarray(env.render()))

    run_trial(
        _allocator(args),
        seed=args.seed,
        convergence_s=0.0,
        measured_s=args.minutes * 60.0,
        on_step=grab,
        preset=args.preset,
        render_mode="rgb_array",
        decision_interval_s=args.frame_s,
        **parse_key_values(args.set, "--set", "source_service_s=15"),
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
    from agents.analysis import plots

    if args.what == "interference":
        source = args.source or BENCHMARKS / "results" / "interference.csv"
        plots.interference_curve(_existing(source), args.out)
    elif args.what == "table1":
        return _run_script("table1", table1_redraw_args(_existing(args.source)))
    else:
        trials = {}
        for source in args.source_list:
            result = TrialResult.load(_existing(source))
            trials[result.label or Path(source).stem] = result
        if args.what == "timeline":
            plots.allocation_timeline(trials, args.out, args.from_h, args.to_h)
        else:
            if len(trials) != 1:
                raise ValueError(f"q takes one trial file, given {len(trials)}; allowed: one")
            plots.q_trajectories(next(iter(trials.values())), args.out)
    print(f"wrote {args.out}")
    return 0


def table1_redraw_args(folder: Path) -> list[str]:
    """The `benchmarks/table1.py` arguments that made the results in `folder`, read back from its
    `table1.json` and saved trials, so that rerunning loads every trial and only redraws."""
    settings = json.loads(_existing(folder / "table1.json").read_text())["metadata"]["settings"]
    found = {p.stem.rsplit("_seed", 1)[0] for p in (folder / "trials").glob("*.json")}
    order = ["softmax", "epsilon", "random"]  # table1.py's own order of its columns
    conditions = sorted(found, key=lambda c: (order.index(c) if c in order else len(order), c))
    if not conditions:
        raise ValueError(
            f"{folder}/trials holds no saved trials; allowed: a table1.py output folder"
        )
    argv = ["--out", str(folder), "--conditions", ",".join(conditions)]
    for key in ("preset", "trials", "convergence_h", "measured_h", "init", "temperature"):
        argv += [f"--{key.replace('_', '-')}", str(settings[key])]
    argv += ["--epsilon", str(settings["epsilon"]), "--seed", str(settings["seed"])]
    for key, value in settings.get("overrides", {}).items():
        argv += ["--set", f"{key}={json.dumps(value)}"]
    return argv


def _existing(path: str | Path) -> Path:
    if not Path(path).exists():
        raise ValueError(
            f"{path} does not exist; allowed: a results file written by tavc or a benchmark"
        )
    return Path(path)


def _run_script(name: str, argv: Sequence[str]) -> int:
    path = BENCHMARKS / f"{name}.py"
    if not path.exists():
        raise ValueError(
            f"benchmark script {path} is missing; the benchmarks live in the source checkout: "
            "clone the repository and pip install -e . there"
        )
    # run it as `python benchmarks/<name>.py <argv>` would, then put the interpreter back
    saved_argv = sys.argv
    sys.argv = [str(path), *argv]
    sys.path.insert(0, str(BENCHMARKS))
    try:
        runpy.run_path(str(path), run_name="__main__")
    except SystemExit as done:
        return int(done.code or 0) if not isinstance(done.code, str) else 1
    finally:
        sys.path.remove(str(BENCHMARKS))
        sys.argv = saved_argv
    return 0


def benchmark_names() -> list[str]:
    return sorted(p.stem for p in BENCHMARKS.glob("*.py") if not p.stem.startswith("_"))


def parser() -> argparse.ArgumentParser:
    top = argparse.ArgumentParser(
        prog="tavc",
        description="Multi-robot task allocation in the prioritized transportation arena of Dahl, "
        "Mataric & Sukhatme (DARS 2004).",
        epilog="Examples: tavc trial --allocator softmax_tavc --hours 2 | "
        "tavc record --minutes 5 --out arena.gif | tavc reproduce | tavc bench allocators --quick",
    )
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")

    trial = sub.add_parser(
        "trial",
        help="run one trial and print a summary",
        description="Run one trial: a convergence period, then a measured period whose delivered "
        "value, switches and time shares are printed. Team allocators "
        f"({', '.join(sorted(TEAMS))}) coordinate the robots; the others are per robot.",
    )
    _trial_options(trial)
    trial.add_argument("--convergence-h", type=float, default=15.0, help="default 15 (the paper's)")
    trial.add_argument("--hours", type=float, default=5.0, help="measured hours (default 5)")
    trial.add_argument("--out", type=Path, default=None, help="save the full result as JSON")
    trial.set_defaults(run=cmd_trial)

    record = sub.add_parser(
        "record",
        help="record a trial to an animated GIF (or its last frame to a PNG)",
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
        help="plot saved results (no rerun): timeline, q, interference",
        description="Draw a figure from saved results. timeline: which circuit each robot served "
        "over time, one panel per trial file (from `tavc trial --out` or a benchmark's saved "
        "trials); q: the learners' Q(high) - Q(other) over time, fast against slow; interference: "
        "the interference curve t(n) from benchmarks/results/interference.csv; table1: Table 1's "
        "reports and figures redrawn from a table1.py output folder's saved trials.",
    )
    plot.add_argument("what", choices=["timeline", "q", "interference", "table1"])
    plot.add_argument(
        "source_list",
        nargs="*",
        metavar="FILE",
        help="trial JSON file(s) (timeline, q), interference.csv (default: the committed one), "
        "or a table1.py output folder (table1)",
    )
    plot.add_argument("--from-h", type=float, default=None, help="timeline: start (hours)")
    plot.add_argument("--to-h", type=float, default=None, help="timeline: end (hours)")
    plot.add_argument("--out", type=Path, default=Path("plot.png"), help="the PNG to write")
    plot.set_defaults(run=cmd_plot)

    reproduce = sub.add_parser(
        "reproduce",
        help="reproduce the paper's Table 1 (benchmarks/table1.py)",
        description="Run benchmarks/table1.py with the arguments that follow (see "
        "`tavc reproduce --help` of the script: tavc reproduce -- --help).",
    )
    reproduce.add_argument("script_args", nargs=argparse.REMAINDER)
    reproduce.set_defaults(run=lambda a: _run_script("table1", _strip(a.script_args)))

    bench = sub.add_parser(
        "bench",
        help="run a benchmark script from benchmarks/",
        description="Run benchmarks/NAME.py with the arguments that follow; "
        f"NAME is one of: {', '.join(benchmark_names()) or '(no checkout found)'}.",
    )
    bench.add_argument("name", help="the script's name, e.g. allocators")
    bench.add_argument("script_args", nargs=argparse.REMAINDER)
    bench.set_defaults(run=lambda a: _run_script(a.name, _strip(a.script_args)))
    return top


def _strip(args: Sequence[str]) -> list[str]:
    return list(args[1:]) if args and args[0] == "--" else list(args)


def main(argv: Sequence[str] | None = None) -> int:
    top = parser()
    args = top.parse_args(argv)
    if getattr(args, "name", None) is not None and args.name not in benchmark_names():
        top.error(f"benchmark {args.name!r} is unknown; allowed: {benchmark_names()}")
    for name in ("hours", "minutes", "frame_s", "fps"):
        value = getattr(args, name, None)
        if value is not None and not value > 0:
            top.error(f"--{name.replace('_', '-')} = {value}; allowed: a number > 0")
    if getattr(args, "what", None) is not None:
        args.source = args.source_list[0] if args.source_list else None
        if args.what != "interference" and not args.source_list:
            top.error(
                f"plot {args.what} needs its input; allowed: trial JSON file(s) for timeline and "
                "q, a table1.py output folder for table1"
            )
    if getattr(args, "convergence_h", 0.0) < 0:
        top.error(f"--convergence-h = {args.convergence_h}; allowed: a number >= 0")
    try:
        code: int = args.run(args)
    except ValueError as error:
        top.error(str(error))
    return code


if __name__ == "__main__":
    sys.exit(main())
