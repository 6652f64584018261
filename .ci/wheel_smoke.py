"""Smoke tests of an installed wheel, run by .ci/run from a folder outside the source tree.

    python .ci/wheel_smoke.py --no-extras   # the wheel alone: commands that need an extra say so
    python .ci/wheel_smoke.py               # with the bench and render extras and the example plugin

Both: the package imports from the wheel (not the checkout), `tavc --version` and
`python -m tavc_agents` answer, and every command of docs/cli.md runs in a quick variant (the
table `QUICK` must cover each one, so a command added to the page without one fails here). Without
extras, the commands that need one end with one line naming it and exit code 2. With them: the
env passes PettingZoo's checker, a trial runs, and the example plugin's allocators
(tests/plugin/tavc_example_plugin) run by name in `tavc trial`, a sweep and a study program of the
source tree run against the installed wheel. Both: the wheel ships no study, and every module in it
imports (or, without extras, fails with one line naming the extra it needs).
"""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1]
TAVC = [sys.executable, "-m", "tavc_agents"]
SCRIPT = Path(sys.executable).parent / "tavc"  # the console script the wheel installs
BENCH_QUICK = "--presets dahl2004 --trials 2 --convergence-h 0.05 --measured-h 0.05 --workers 2"

# docs/cli.md's commands -> their quick variants (and the extra each needs, if any)
QUICK: dict[str, tuple[str, str | None]] = {
    "tavc trial --allocator softmax_tavc --measured-h 2 --out trial.json": (
        "trial --allocator softmax_tavc --convergence-h 0.05 --measured-h 0.1 --out trial.json",
        None,
    ),
    "tavc trial --allocator auction --preset three_circuits_three_classes --param rate=0.1": (
        "trial --allocator auction --preset three_circuits_three_classes --param rate=0.1 "
        "--convergence-h 0 --measured-h 0.1",
        None,
    ),
    "tavc record --allocator softmax_tavc --minutes 3 --out arena.gif": (
        "record --allocator softmax_tavc --minutes 0.5 --out arena.gif",
        "render",
    ),
    "tavc evaluate --allocator greedy --scenario passing --out row.json": (
        "evaluate --allocator greedy --scenario passing --seeds 3 --out row.json",
        None,
    ),
    "tavc plot timeline trial.json --out timeline.png": (
        "plot timeline trial.json --out timeline.png",
        "plot",
    ),
    "tavc plot curve benchmarks/results/marl/torchrl_mappo_dahl2004 --out curve.png": (
        f"plot curve {SOURCE}/benchmarks/results/marl/torchrl_mappo_dahl2004 --out curve.png",
        "plot",
    ),
    "tavc --version": ("--version", None),
}


def documented() -> list[str]:
    """The `tavc ...` command lines of docs/cli.md's first code block, without their comments."""
    text = (SOURCE / "docs" / "cli.md").read_text(encoding="utf-8")
    block = text.split("```bash\n", 1)[1].split("```", 1)[0]
    return [line.split("  #")[0].strip() for line in block.splitlines() if line.startswith("tavc")]


def tavc(args: str, *, expect: int = 0, script: bool = False) -> str:
    """Run `tavc args` (the console script, or `python -m tavc_agents`); its output."""
    command = [str(SCRIPT)] if script else TAVC
    done = subprocess.run([*command, *args.split()], capture_output=True, text=True)
    if done.returncode != expect:
        sys.exit(
            f"tavc {args}: exit code {done.returncode}, expected {expect}\n{done.stdout}\n"
            f"{done.stderr}"
        )
    print(f"ok{f' (exit code {expect})' if expect else ''}: tavc {args}", flush=True)
    return done.stdout + done.stderr


def check_installed() -> None:
    import tavc_agents
    import tavc_env

    for module in (tavc_env, tavc_agents):
        where = Path(module.__file__ or "").resolve()
        if SOURCE in where.parents:
            sys.exit(
                f"{module.__name__} was imported from the source tree ({where}), not the wheel"
            )
    version = f"tavc {tavc_env.__version__}\n"
    if tavc("--version", script=True) != version or tavc("--version") != version:
        sys.exit(f"tavc --version does not print {version!r}")
    tavc("--help")


def check_commands(extras: bool) -> None:
    missing = sorted(set(documented()) - set(QUICK))
    if missing:
        sys.exit(f"docs/cli.md commands without a quick variant in .ci/wheel_smoke.py: {missing}")
    if not extras:  # the example: a model-based allocator needs no extra (nor checkout)
        tavc("trial --allocator auction --preset three_circuits_three_classes --measured-h 0.2")
    for quick, extra in QUICK.values():
        if extras or extra is None:
            tavc(quick)
            continue
        said = tavc(quick, expect=2).strip()
        wanted = f"pip install 'tavc-env[{extra}]'"
        if "\n" in said or not said.endswith(wanted):
            sys.exit(
                f"tavc {quick} without the {extra} extra said {said!r}, not one line ending {wanted}"
            )
        print(f"    {said}")


def check_library_and_plugin() -> None:
    from pettingzoo.test import parallel_api_test

    import tavc_env
    from tavc_agents.experiments.registry import allocator_names
    from tavc_agents.experiments.runner import run_trial
    from tavc_agents.experiments.sweep import TrialSpec, run_sweep
    from tavc_agents.learners.tavc import softmax_tavc

    env = tavc_env.parallel_env(max_sim_time_s=1800.0)
    parallel_api_test(env, num_cycles=50)
    env.reset(seed=1)
    env.step(dict.fromkeys(env.agents, 0))
    assert copy.deepcopy(env).sim_time_s == env.sim_time_s
    result = run_trial(lambda agent: softmax_tavc(), seed=0, convergence_s=1800.0, measured_s=600.0)
    assert result.delivery_time_s, "no delivery in a 40-minute trial"

    plugins = ["example_greedy_reward", "example_split"]  # the example plugin's entry points
    assert set(plugins) <= set(allocator_names()), allocator_names()
    for name in plugins:
        tavc(f"trial --allocator {name} --convergence-h 0.02 --measured-h 0.05")
    specs = [
        TrialSpec(key=n, allocator=n, seed=0, convergence_s=60, measured_s=120) for n in plugins
    ]
    assert sorted(run_sweep(specs, "plugin_sweep", workers=2)) == plugins
    print("ok: a sweep of the plugin's allocators in 2 worker processes")
    # a study program of the source tree, run against the installed wheel, takes the plugins too
    study = [sys.executable, str(SOURCE / "benchmarks" / "allocators.py"), *BENCH_QUICK.split()]
    done = subprocess.run(
        [*study, "--plugins", *plugins, "--out", "plugin_bench"], capture_output=True, text=True
    )
    said = done.stdout + done.stderr
    assert done.returncode == 0 and all(f"| {name} |" in said for name in plugins), said
    print("ok: benchmarks/allocators.py against the installed wheel, with the plugin's allocators")
    # the evaluation protocol from the wheel: a plugin's allocator by name, and `stay` on
    # bad_start reproducing the committed reference (the package data) exactly
    said = tavc(f"evaluate --allocator {plugins[1]} --scenario passing --seeds 4")
    assert "| passing | 4 |" in said, said
    import numpy as np

    from tavc_agents import evaluate
    from tavc_env.scenarios import SCENARIOS

    stay = evaluate("stay", "bad_start", workers=2)
    values = [e.value_per_hour for e in stay.episodes]
    committed = SCENARIOS["bad_start"].references
    assert committed is not None and float(np.mean(values)) == committed.stay_per_h, (
        values,
        committed,
    )
    print(f"ok: stay on bad_start from the wheel: {committed.stay_per_h} per hour, as committed")


def check_wheel_modules(extras: bool) -> None:
    """The wheel holds the library and the user commands, no study; each of its modules imports,
    or fails with an ImportError that names the extra it needs (`extras`: what was installed)."""
    import importlib
    import pkgutil

    import tavc_agents
    import tavc_env
    from tavc_agents.cli import missing_extra

    names = [
        info.name
        for package in (tavc_env, tavc_agents)
        for info in pkgutil.walk_packages(package.__path__, f"{package.__name__}.")
    ]
    assert not [n for n in names if ".studies" in n], "the wheel ships study modules"
    failed = []
    for name in names:
        if name.endswith("__main__"):
            continue
        try:
            importlib.import_module(name)
        except ImportError as error:
            if missing_extra(error) is None:  # not a missing extra: a bug
                failed.append(f"{name}: {error}")
    if failed:
        sys.exit("modules of the wheel that do not import:\n" + "\n".join(failed))
    print(f"ok: {len(names)} modules of the wheel import (or name their extra)")


def main() -> None:
    extras = "--no-extras" not in sys.argv[1:]
    check_installed()
    check_commands(extras)
    check_wheel_modules(extras)
    if extras:
        check_library_and_plugin()
    import tavc_env

    what = "with extras and the example plugin" if extras else "without extras"
    print(
        f"wheel smoke {what}: tavc_env {tavc_env.__version__} from {Path(tavc_env.__file__).parent}: ok"
    )


if __name__ == "__main__":
    main()
