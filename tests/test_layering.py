"""The house's layering: imports only go down, and nothing imports in a circle.

Every import of the package's own modules is read from the source (also those inside functions
and under `TYPE_CHECKING`), so a function-level import cannot hide an upward arrow. Layers, lowest
first; a module may import from its own layer or any layer below, and the import graph of the
whole tree must have no cycle (checked with the standard library's topological sorter).
"""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# (layer, module prefix): the longest matching prefix decides a module's layer.
LAYERS: list[tuple[int, str]] = [
    (0, "tavc_env.validation"),  # public: the argument checks every layer uses
    (0, "tavc_env.safe_files"),  # public safe readers: every reader of the project uses them
    (0, "tavc_env.layout"),
    (0, "tavc_env.config"),
    (0, "tavc_env.metrics"),
    (1, "tavc_env.engine"),
    (1, "tavc_env.twin.tables"),  # the model twin's engine and its tables: engine-level
    (1, "tavc_env.twin.engine"),
    (2, "tavc_env.render"),
    (2, "tavc_env.observations"),
    (2, "tavc_env.options"),  # the env's own options, beside the arena's config
    (2, "tavc_env.measurement"),  # fixed-allocation runs of the physics engine
    (2, "tavc_env.twin.measure"),  # the twin's tables measured with them
    (3, "tavc_env.env"),
    (3, "tavc_env.twin"),  # the twin's env (and the package's public names)
    (3, "tavc_env.scenarios"),  # arenas with schedules and evaluation protocols
    (3, "tavc_env.arena"),  # which arena: scenario or preset, by name or value, resolved once
    (3, "tavc_env.registration"),
    (3, "tavc_env.v0"),
    (3, "tavc_env"),  # the package's __init__: the public API, re-exporting the env
    (4, "tavc_env.adapters"),  # views of the env for learning libraries
    (4, "tavc_env.adapters.batched"),  # N arenas in worker processes, results stacked
    (4, "tavc_agents.policy"),
    (4, "tavc_agents.driver"),
    (4, "tavc_agents.model"),
    (5, "tavc_agents.learners"),
    (5, "tavc_agents.allocators"),
    (6, "tavc_agents.experiments"),
    (6, "tavc_agents.envs"),
    (7, "tavc_agents.analysis"),
    (7, "tavc_agents.learning_runs"),  # what the examples that train with a library need
    (8, "tavc_agents.evaluation"),  # the suite's protocol: episodes, metric, references, IQM
    (9, "tavc_agents.cli"),
    (9, "tavc_agents.__main__"),  # `python -m tavc_agents`: the cli
    (9, "tavc_agents"),  # the package's __init__ (a docstring)
    (10, "benchmarks.arena_analysis"),  # what several studies share, beside them
    (10, "benchmarks.arena_runs"),
    (11, "benchmarks"),  # the study programs: they import the package and the shared modules
]
SHARED_BESIDE_STUDIES = ("benchmarks.arena_analysis", "benchmarks.arena_runs")
# physics, task rules and the twin's engine: must not know gymnasium or PettingZoo
ENGINE_ONLY = ("tavc_env.engine", "tavc_env.twin.tables", "tavc_env.twin.engine")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[0] == "agents":  # a source folder: its package is `tavc_agents`
        parts.pop(0)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def source_files() -> dict[str, Path]:
    files = [*ROOT.glob("tavc_env/**/*.py"), *ROOT.glob("agents/tavc_agents/**/*.py")]
    files += ROOT.glob("benchmarks/*.py")
    return {module_name(p): p for p in sorted(files)}


MODULES = source_files()


def imported_modules(path: Path, name: str) -> set[str]:
    """Every module `path` imports, at any depth of its code, resolved to full names."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                stem = ".".join([*base, node.module] if node.module else base)
            else:
                stem = node.module or ""
            found.add(stem)
            # `from package import module` imports the module itself
            found.update(f"{stem}.{alias.name}" for alias in node.names)
    return found


def own(target: str) -> str | None:
    """The project module `target` refers to (itself or the package it names), or None. A study
    program imports the modules beside it by their bare names (`import arena_runs`)."""
    if f"benchmarks.{target.partition('.')[0]}" in MODULES:
        return f"benchmarks.{target.partition('.')[0]}"
    while target:
        if target in MODULES:
            return target
        target = target.rpartition(".")[0]
    return None


def layer_of(name: str) -> int:
    matches = [
        (len(prefix), layer)
        for layer, prefix in LAYERS
        if name == prefix or name.startswith(prefix + ".")
    ]
    if not matches:
        raise AssertionError(f"module {name} has no layer; add it to LAYERS in {__file__}")
    return max(matches)[1]


def graph() -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {}
    for name, path in MODULES.items():
        targets = {own(t) for t in imported_modules(path, name)}
        edges[name] = {t for t in targets if t is not None and t != name}
    return edges


EDGES = graph()


def test_every_module_has_a_layer() -> None:
    for name in MODULES:
        layer_of(name)


def test_imports_only_go_down() -> None:
    upward = [
        f"{name} (layer {layer_of(name)}) imports {target} (layer {layer_of(target)})"
        for name, targets in EDGES.items()
        for target in sorted(targets)
        if layer_of(target) > layer_of(name)
    ]
    assert not upward, "imports that run up:\n" + "\n".join(upward)


def test_no_import_cycles() -> None:
    # A package's __init__ importing its own submodules is the usual re-export, not a cycle of
    # meaning; it is left out so that real cycles between modules show.
    edges = {
        name: {t for t in targets if not name or not t.startswith(name + ".")}
        for name, targets in EDGES.items()
    }
    try:
        tuple(graphlib.TopologicalSorter(edges).static_order())
    except graphlib.CycleError as error:
        pytest.fail(f"import cycle: {' -> '.join(error.args[1])}")


def test_nothing_in_the_wheel_imports_the_benchmarks() -> None:
    importers = [
        f"{name} imports {target}"
        for name, targets in EDGES.items()
        for target in targets
        if target.startswith("benchmarks") and not name.startswith("benchmarks")
    ]
    assert not importers, "\n".join(importers)
    for name, path in MODULES.items():
        if name.startswith("benchmarks"):
            text = path.read_text(encoding="utf-8")
            for trick in ("sys.path", "runpy", "importlib.import_module"):
                assert trick not in text, f"{path} uses {trick}"


def test_no_study_imports_another_study() -> None:
    """The study programs are leaves: each imports the package and the shared modules beside the
    studies, never another study."""
    crossing = [
        f"{name} imports {target}"
        for name, targets in EDGES.items()
        if name.startswith("benchmarks.")
        for target in targets
        if target.startswith("benchmarks.") and target not in SHARED_BESIDE_STUDIES
    ]
    assert not crossing, "\n".join(crossing)
    assert EDGES["benchmarks.passing"] >= {"benchmarks.arena_runs"}  # the check sees bare imports


def test_the_engine_knows_nothing_of_rl_libraries() -> None:
    for name, path in MODULES.items():
        if name.startswith(ENGINE_ONLY):
            imported = imported_modules(path, name)
            rl = sorted(m for m in imported if m.split(".")[0] in {"gymnasium", "pettingzoo"})
            assert not rl, f"{name} imports {rl}"


# What lies under the env's public floors: the engine's modules (the agent library reaches the
# engine through the public API: `tavc_env.Simulation`, `tavc_env.measurement`, the env's methods
# and infos) and any name starting with "_". The study programs of benchmarks/ are held to it too.
INTERNALS = ("tavc_env.engine.", *(f"{m}." for m in ENGINE_ONLY[1:]))


def private_or_internal(target: str) -> bool:
    """Whether an imported `tavc_env` module or name is private or an engine internal."""
    if not target.startswith("tavc_env."):
        return False
    parts = target.split(".")
    private = any(
        p.startswith("_") and not (p.startswith("__") and p.endswith("__")) for p in parts
    )
    return private or target.startswith(INTERNALS)


def test_nothing_outside_the_env_uses_its_private_floors() -> None:
    examples = {f"docs.examples.{p.stem}": p for p in sorted(ROOT.glob("docs/examples/*.py"))}
    users = {
        name: path
        for name, path in {**MODULES, **examples}.items()
        if not name.startswith("tavc_env")
    }
    found = [
        f"{name} imports {target}"
        for name, path in users.items()
        for target in sorted(imported_modules(path, name))
        if private_or_internal(target)
    ]
    assert not found, "private names or engine internals used outside tavc_env:\n" + "\n".join(
        found
    )


def test_the_floor_check_sees_private_names(tmp_path: Path) -> None:
    path = tmp_path / "probe.py"
    path.write_text(
        "from tavc_env._validation import require\nfrom tavc_env.env import _hidden\n"
        "from tavc_env.engine.tasks import Phase\nfrom tavc_env import __version__, engine\n"
    )
    found = {t for t in imported_modules(path, "probe") if private_or_internal(t)}
    assert found == {
        "tavc_env._validation",
        "tavc_env._validation.require",
        "tavc_env.env._hidden",
        "tavc_env.engine.tasks",
        "tavc_env.engine.tasks.Phase",
    }


def test_the_layering_test_sees_function_level_imports(tmp_path: Path) -> None:
    """The checker itself: an import inside a function is found (a test that could not fail
    would prove nothing)."""
    path = tmp_path / "probe.py"
    path.write_text(
        "def f():\n    from tavc_agents.experiments import study\n    import tavc_env.env\n"
    )
    found = imported_modules(path, "probe")
    assert {"tavc_agents.experiments", "tavc_agents.experiments.study", "tavc_env.env"} <= found


def longest_chain(edges: dict[str, set[str]]) -> list[str]:
    """The longest chain of imports (a module, one it imports, one that imports, ...)."""
    memo: dict[str, list[str]] = {}

    def chain(name: str) -> list[str]:
        if name not in memo:
            memo[name] = [name, *max((chain(t) for t in edges.get(name, ())), key=len, default=[])]
        return memo[name]

    return max((chain(n) for n in edges), key=len)


def test_the_wheels_longest_import_chain_is_at_most_15_modules() -> None:
    """Issue 36: a house of few floors (VMAS 16, BenchMARL 13). A package's `__init__` importing
    its own submodules is the usual re-export and not counted, as in the cycle check."""
    wheel = {
        name: {
            t for t in targets if not t.startswith("benchmarks") and not t.startswith(name + ".")
        }
        for name, targets in EDGES.items()
        if not name.startswith("benchmarks")
    }
    chain = longest_chain(wheel)
    assert len(chain) <= 15, " -> ".join(chain)
    assert longest_chain({"a": {"b"}, "b": {"c"}, "c": set()}) == ["a", "b", "c"]
