"""The open registry: allocators registered at run time and from installed packages' `tavc.allocators`
entry points, by name in `make_allocator`, sweeps (also in spawned workers) and `tavc trial`; and
the errors of bad names, factories and plugins.

A plugin is "installed" here as pip would leave it for importlib.metadata: a `.dist-info` folder
with its `entry_points.txt` on the path, beside the example plugin's source
(`tests/plugin/tavc_example_plugin`, which CI also installs with pip)."""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path
from types import ModuleType

import pytest

from tavc_agents.experiments.registry import (
    BUILT_IN,
    REGISTRY,
    AllocatorRegistry,
    PluginError,
    make_allocator,
    team_allocator,
)
from tavc_agents.experiments.runner import TrialResult, run_trial
from tavc_agents.learners.tavc import softmax_tavc
from tavc_agents.policy import Team

PLUGIN_SOURCE = Path(__file__).resolve().parents[2] / "plugin" / "tavc_example_plugin"
GROUP = "tavc.allocators"
EXAMPLE = {
    "example_greedy_reward": "tavc_example_plugin:BestRewardSoFar",
    "example_split": "tavc_example_plugin:split_team",
}
BROKEN = {
    "example_broken": "tavc_example_plugin.nowhere:Thing",
    "example_not_callable": "tavc_example_plugin:__doc__",
    "random": "tavc_example_plugin:BestRewardSoFar",  # a built-in's name
}
SHORT = {"convergence_s": 60.0, "measured_s": 120.0}


def install(site: Path, name: str, points: dict[str, str]) -> Path:
    """A distribution `name` 0.1 in `site` as pip installs one: its dist-info with entry points."""
    info = site / f"{name.replace('-', '_')}-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    lines = [f"[{GROUP}]", *(f"{k} = {v}" for k, v in points.items())]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return site


@pytest.fixture
def plugin_site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The example plugin installed (for this test's process), and its paths."""
    site = install(tmp_path / "site", "tavc-example-plugin", EXAMPLE)
    monkeypatch.syspath_prepend(str(PLUGIN_SOURCE))
    monkeypatch.syspath_prepend(str(site))
    return site


@pytest.fixture
def example(monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    """The example plugin's module, importable without its entry points (for run-time tests)."""
    monkeypatch.syspath_prepend(str(PLUGIN_SOURCE))
    return importlib.import_module("tavc_example_plugin")


def fresh() -> AllocatorRegistry:
    return AllocatorRegistry(BUILT_IN)  # a registry of its own: tests leave REGISTRY alone


def assert_fixed_split(result: TrialResult, offset: int) -> None:
    """Robot k moved (at most once) to circuit (k + offset) mod n and stayed there."""
    n = len(result.values)
    last = list(result.initial_circuits)
    for robot in range(len(last)):
        moves = [c for _, r, c in result.changes if r == robot]
        assert len(moves) <= 1
        last[robot] = moves[-1] if moves else last[robot]
    assert last == [(k + offset) % n for k in range(len(last))]


# -- run-time registration --------------------------------------------------------------------------
def test_built_in_allocators_by_kind() -> None:
    registry = AllocatorRegistry(BUILT_IN, group=None)
    per_robot = {"softmax_tavc", "epsilon_tavc", "own_reward", "random", "fixed", "stay"}
    teams = {"static", "greedy", "auction", "response_threshold", "network"}
    assert registry.names(team=False) == sorted(per_robot)
    assert registry.names(team=True) == sorted(teams)
    assert registry.names() == sorted(per_robot | teams)


def test_register_a_policy_and_a_team_and_run_them(example: ModuleType) -> None:
    registry = fresh()
    registry.register("mine", example.BestRewardSoFar)
    registry.register("my_team", example.SplitTeam, team=True)
    assert {"mine", "my_team"} <= set(registry.names())
    assert registry.names(team=True).count("my_team") == 1
    policy = registry.make_policy("mine", explore=2)
    assert isinstance(policy, example.BestRewardSoFar) and policy.explore == 2
    team = registry.make_allocator("my_team", offset=1)
    assert isinstance(team, Team)
    assert_fixed_split(run_trial(team, seed=0, **SHORT), offset=1)
    with pytest.raises(ValueError, match=r"allocator 'mine' has no parameter bogus; allowed: expl"):
        registry.make_allocator("mine", bogus=1)
    with pytest.raises(ValueError, match=r"'my_team' is not a per-robot policy \(a team"):
        registry.make_policy("my_team")
    assert [a.name for a in registry.registered_at_run_time()] == ["mine", "my_team"]


def test_register_refuses_taken_and_bad_names_and_factories() -> None:
    registry = fresh()
    with pytest.raises(ValueError, match=r"allocator 'random' is taken \(built in\); allowed: ano"):
        registry.register("random", softmax_tavc)
    registry.register("random", softmax_tavc, replace=True)
    assert registry.get("random").origin == "registered at run time"
    registry.register("twice", softmax_tavc)
    with pytest.raises(ValueError, match=r"'twice' is taken \(registered at run time\)"):
        registry.register("twice", softmax_tavc)
    for bad in ("", "two words", "a=b", "1st", 3):
        with pytest.raises(ValueError, match=r"allocator name .* is invalid; allowed: a letter"):
            registry.register(bad, softmax_tavc)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"factory of allocator 'x' is 42, which is not callable"):
        registry.register("x", 42)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"allocator 'nope' is unknown; allowed: \[.*'twice'"):
        registry.make_allocator("nope")


def test_a_factory_of_the_wrong_kind_is_named(example: ModuleType) -> None:
    SplitTeam = example.SplitTeam
    registry = fresh()
    registry.register("team_as_policy", SplitTeam)  # team=True forgotten
    with pytest.raises(ValueError, match=r"is a per-robot policy, but its factory made 'SplitTe"):
        registry.make_allocator("team_as_policy")
    registry.register("policy_as_team", softmax_tavc, team=True)
    with pytest.raises(ValueError, match=r"'policy_as_team' .* is a team allocator, but its fac"):
        registry.make_allocator("policy_as_team")
    marked = team_allocator(SplitTeam)  # what an entry point names; also accepted here
    registry.register("marked", marked)
    assert registry.get("marked").team


# -- entry points ------------------------------------------------------------------------------------
def test_entry_points_are_found_by_name(plugin_site: Path) -> None:
    registry = fresh()
    assert {"example_greedy_reward", "example_split"} <= set(registry.names())
    assert registry.get("example_split").team and not registry.get("example_greedy_reward").team
    assert "tavc-example-plugin 0.1" in registry.get("example_split").origin
    team = registry.make_allocator("example_split")
    assert_fixed_split(run_trial(team, seed=1, **SHORT), offset=0)
    per_robot = registry.make_allocator("example_greedy_reward", explore=1)
    assert callable(per_robot) and run_trial(per_robot, seed=1, **SHORT).delivery_time_s
    with pytest.raises(ValueError, match=r"'example_split' is taken \(entry point example_split ="):
        fresh().register("example_split", softmax_tavc)  # known, not loaded yet
    with pytest.raises(ValueError, match=r"'example_split' is taken \(entry point example_split ="):
        registry.register("example_split", softmax_tavc)  # loaded


def test_a_broken_plugin_is_named_not_a_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, example: ModuleType
) -> None:
    site = install(tmp_path / "site", "tavc-broken-plugin", BROKEN)
    monkeypatch.syspath_prepend(str(site))
    with pytest.warns(UserWarning, match=r"entry point random = .* of tavc-broken-plugin 0.1 is i"):
        registry = fresh()
        assert "example_broken" in registry.names()
    with pytest.raises(
        PluginError,
        match=r"allocator 'example_broken' could not be loaded from the entry point "
        r"example_broken = 'tavc_example_plugin.nowhere:Thing' of tavc-broken-plugin 0.1: "
        r"ModuleNotFoundError",
    ):
        registry.make_allocator("example_broken")
    with pytest.raises(PluginError, match=r"'example_not_callable': the entry point .* not call"):
        registry.get("example_not_callable")
    assert registry.get("random").origin == "built in"  # the built-in keeps its name
    with warnings.catch_warnings(record=True) as caught:  # listing by kind loads them all
        warnings.simplefilter("always")
        assert "example_broken" not in registry.names(team=False)
    assert sorted(str(w.message).split("'")[1] for w in caught) == [
        "example_broken",
        "example_not_callable",
    ]


EXITING = {
    "example_exits": "tavc_exiting_plugin:Thing",
    "example_raises_base": "tavc_base_plugin:Thing",
}


def exiting_plugins(site: Path) -> Path:
    """Two plugins whose import calls sys.exit(3) or raises a BaseException of its own."""
    site.mkdir(parents=True, exist_ok=True)
    (site / "tavc_exiting_plugin.py").write_text("import sys\nsys.exit(3)\n")
    (site / "tavc_base_plugin.py").write_text(
        "class Stop(BaseException):\n    pass\n\nraise Stop('no')\n"
    )
    return install(site, "tavc-exiting-plugin", EXITING)


def test_a_plugin_that_exits_or_raises_a_base_exception_at_import_is_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # defect 9 of issue 35: sys.exit at import ended `tavc trial` with its code and no message
    site = exiting_plugins(tmp_path / "site")
    monkeypatch.syspath_prepend(str(site))
    registry = fresh()
    with pytest.raises(PluginError) as caught:
        registry.get("example_exits")
    message = str(caught.value)
    assert "allocator 'example_exits' could not be loaded from the entry point" in message
    assert "tavc-exiting-plugin 0.1: importing it called sys.exit(3)" in message
    with pytest.raises(PluginError, match=r"'example_raises_base' could not .*: Stop: no"):
        registry.get("example_raises_base")
    done = subprocess.run(
        [sys.executable, "-m", "tavc_agents", "trial", "--allocator", "example_exits"],
        capture_output=True,
        text=True,
        env=subprocess_env(site),
        timeout=120,
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "importing it called sys.exit(3)" in done.stderr


def test_entry_point_names_register_refuses_are_neither_listed_nor_usable(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # defect 9 of issue 35: entry-point names that register_allocator refuses were listed and used
    points = {"9lives": EXAMPLE["example_split"], "has space": EXAMPLE["example_split"]}
    site = install(tmp_path / "site", "tavc-odd-names", points)
    monkeypatch.syspath_prepend(str(PLUGIN_SOURCE))
    monkeypatch.syspath_prepend(str(site))
    registry = fresh()
    with pytest.warns(UserWarning) as caught:
        names = registry.names()
    assert "9lives" not in names and "has space" not in names
    shown = sorted(str(w.message) for w in caught)
    assert len(shown) == 2 and all(
        "\n" not in m and "is invalid; allowed: a letter" in m for m in shown
    )
    assert "the name '9lives' is invalid" in shown[0] and "tavc-odd-names 0.1" in shown[0]
    with pytest.raises(PluginError, match=r"allocator '9lives' of the entry point .* is refused"):
        registry.make_allocator("9lives")
    with pytest.raises(ValueError, match=r"allocator name '9lives' is invalid"):
        registry.register("9lives", softmax_tavc)  # the same rule


def subprocess_env(site: Path) -> dict[str, str]:
    paths = [str(site), str(PLUGIN_SOURCE), os.environ.get("PYTHONPATH", "")]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in paths if p)}


def test_tavc_trial_runs_a_plugin_and_names_a_broken_one(tmp_path: Path) -> None:
    site = install(tmp_path / "site", "tavc-example-plugin", EXAMPLE)
    install(site, "tavc-broken-plugin", {"example_broken": BROKEN["example_broken"]})
    env = subprocess_env(site)
    tavc = [sys.executable, "-m", "tavc_agents", "trial", "--convergence-h", "0.01"]
    for name in ("example_split", "example_greedy_reward"):
        done = subprocess.run(
            [*tavc, "--measured-h", "0.02", "--allocator", name],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
        assert done.returncode == 0, done.stderr
        assert f"{name} on dahl2004, seed 0" in done.stdout
    done = subprocess.run(
        [*tavc, "--allocator", "example_broken"], capture_output=True, text=True, env=env
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "allocator 'example_broken' could not be loaded from the entry point" in done.stderr


def test_a_sweep_with_spawned_workers_runs_plugins_and_run_time_registrations(
    tmp_path: Path,
) -> None:
    site = install(tmp_path / "site", "tavc-example-plugin", EXAMPLE)
    script = textwrap.dedent(
        f"""
        import multiprocessing
        from tavc_agents.experiments.registry import register_allocator
        from tavc_agents.experiments.sweep import TrialSpec, run_sweep
        from tavc_example_plugin import BestRewardSoFar

        if __name__ == "__main__":
            multiprocessing.set_start_method("spawn")  # workers start without the parent's state
            register_allocator("registered_here", BestRewardSoFar)
            names = ["example_split", "example_greedy_reward", "registered_here"]
            specs = [
                TrialSpec(key=n, allocator=n, seed=0, convergence_s=60.0, measured_s=60.0)
                for n in names
            ]
            results = run_sweep(specs, {str(tmp_path / "out")!r}, workers=2)
            print(sorted(results))
            register_allocator("a_lambda", lambda: BestRewardSoFar())
            try:
                run_sweep(specs, {str(tmp_path / "out2")!r}, workers=2)
            except ValueError as error:
                print(error)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=subprocess_env(site),
        timeout=180,
    )
    assert done.returncode == 0, done.stderr
    assert "['example_greedy_reward', 'example_split', 'registered_here']" in done.stdout
    # a factory a spawned worker cannot receive is named before anything runs
    assert "allocator 'a_lambda' was registered at run time with a factory that" in done.stdout
    assert not (tmp_path / "out2").exists() or not list((tmp_path / "out2").glob("*.json"))
    assert sorted(p.name for p in (tmp_path / "out").glob("*.json")) == [
        "example_greedy_reward.json",
        "example_split.json",
        "registered_here.json",
    ]


def test_the_default_registry_builds_by_name() -> None:
    assert make_allocator.__self__ is REGISTRY  # type: ignore[attr-defined]
    assert set(REGISTRY.names()) >= {a.name for a in BUILT_IN}


def test_the_allocators_study_compares_plugins(
    example: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    import allocators
    from tavc_agents import evaluation
    from tavc_agents.model import load_model

    registry = fresh()

    def with_model(model: object, share: float = 0.5) -> object:
        return example.SplitTeam()

    registry.register("mine", example.BestRewardSoFar)
    registry.register("mine_with_model", with_model, team=True)
    monkeypatch.setattr(evaluation, "REGISTRY", registry)  # which factories take the model
    monkeypatch.setattr(allocators, "allocator_names", registry.names)
    settings = allocators.Settings(presets=("dahl2004",), plugins=("mine", "mine_with_model"))
    model = load_model("dahl2004")
    specs = {s.tags["allocator"]: s for s in allocators.specs(settings, {"dahl2004": model})}
    assert list(specs)[-2:] == ["mine", "mine_with_model"]
    assert specs["mine"].allocator == "mine" and dict(specs["mine"].allocator_kwargs) == {}
    assert dict(specs["mine_with_model"].allocator_kwargs) == {"model": model.to_dict()}
    assert settings.recorded()["plugins"] == "['mine', 'mine_with_model']"
    assert "plugins" not in allocators.Settings().recorded()  # reports without plugins unchanged
    with pytest.raises(ValueError, match=r"plugins = \('nope',\) is invalid; allowed: distinct"):
        allocators.Settings(plugins=("nope",))
