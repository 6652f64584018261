"""The leaderboard: every allocator of the package (random, stay, epsilon and softmax TAVC, the
own-reward learner with the default and with the rich observation, response threshold, auction,
greedy, static) on every scenario of the suite (`tavc_env.scenarios`) and its
evaluation seeds; scores normalised between the scenarios' committed references (0 = random, 1 =
the model optimum), interquartile means with bootstrap intervals per scenario and over the suite
(stratified).

Writes `leaderboard.{md,csv,json}`, `leaderboard.png` and every episode under trials/ into a new
run folder under runs/ (git ignores it), `--out`, or with `--update-reference`
benchmarks/results/leaderboard/; `--resume RUN_DIR` continues an interrupted run.

    python benchmarks/leaderboard.py            # 10 allocators x 7 scenarios x 20 seeds of 8 h
    python benchmarks/leaderboard.py --quick    # smoke run
    python benchmarks/leaderboard.py --update-reference --figure-only   # redraw the PNG, run nothing

The leaderboard: every allocator of the package on every scenario of the suite
(`tavc_env.scenarios`), on the scenarios' evaluation seeds, scored as the field reports benchmarks.

Each episode's delivered value per hour (`tavc_env.scenarios.METRIC`) is normalised between the
scenario's committed references (`benchmarks/results/scenarios/references.json`, the `scenarios`
study): `(value - random) / (optimum - random)`, random measured in physics and the optimum the
model's. Per scenario and allocator: the interquartile mean (IQM) of the normalised scores over
seeds with a percentile bootstrap 95 % interval; over the suite, the IQM of all scores with a
stratified bootstrap (seeds resampled within each scenario), as rliable computes them (here with
`scipy.stats.trim_mean` and `scipy.stats.bootstrap`). The learning allocators (TAVC) learn online,
within each episode, from nothing: their score includes their learning. Deep learners trained
offline are evaluated on the same seeds by their own scripts and added to the same table.

`--figure-only` redraws `leaderboard.png` from a finished run's `leaderboard.json` (the table's
IQMs and intervals as reported) without running an episode or writing anything else.
The script is `benchmarks/leaderboard.py`.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, markdown_table, metadata_markdown
from tavc_agents.evaluation import (
    allocators,
    episode_key,
    episode_spec,
    iqm_ci,
    normalised,
    read_row,
    references,
    value_per_hour,
)
from tavc_agents.experiments.files import read_csv, read_report
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.registry import allocator_names
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import (
    EvaluationSettings,
    Outcome,
    ScoredSettings,
    redraw,
    redraw_source,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import TagValue, TrialSpec
from tavc_agents.model import load_model
from tavc_env.scenarios import SCENARIOS

FIGURE = "leaderboard.png"
PANELS_PER_ROW = 4  # eight panels in two rows stay readable at a page's width
Row = dict[str, Any]
SUBMITTED = " (submitted)"  # the mark of a row evaluated elsewhere
DEEP_REPORT = "deep_leaderboard.json"


@dataclass(frozen=True, kw_only=True)
class Settings(EvaluationSettings, ScoredSettings):
    """The leaderboard's settings (its command line)."""

    reference: ClassVar = "leaderboard"
    min_seeds: ClassVar = 2  # an interval needs two
    quick_sizes: ClassVar = {"seeds": 2, "episode_h": 0.5, "resamples": 200}
    recorded_fields: ClassVar = "scenarios seeds_text episode_text resamples seed"

    quick: bool = False
    """smoke run: 2 seeds, 0.5-h episodes, 200 resamples"""
    figure_only: bool = False
    """run nothing: redraw leaderboard.png from the leaderboard.json already in the output folder"""
    plugins: tuple[str, ...] = ()
    """more allocators by registry name (your own, registered through the `tavc.allocators` entry
    point or at run time), run on the same episodes"""
    rows: tuple[Path, ...] = ()
    """leaderboard rows written by `tavc evaluate --out` (or `Evaluation.save`), shown beside the
    allocators; each must hold every episode of this leaderboard"""
    deep: tuple[Path, ...] = ()
    """report folders of `benchmarks/deep_leaderboard.py` (trained networks, scored on the same
    evaluation seeds), shown beside the allocators on the scenarios they trained on"""

    def __post_init__(self) -> None:
        super().__post_init__()
        known = set(allocator_names())
        refuse_invalid(
            self,
            [
                (
                    "plugins",
                    len(set(self.plugins)) == len(self.plugins)
                    and all(p in known for p in self.plugins),
                    f"distinct registered allocators ({', '.join(sorted(known))})",
                ),
                (
                    "rows",
                    all(Path(r).is_file() for r in self.rows),
                    "files written by tavc evaluate --out",
                ),
                (
                    "deep",
                    all((Path(d) / DEEP_REPORT).is_file() for d in self.deep),
                    f"folders holding a {DEEP_REPORT} written by benchmarks/deep_leaderboard.py",
                ),
            ],
        )

    def recorded(self) -> dict[str, Any]:
        # only when given: reports without submissions record what they always did
        extra = {"plugins": list(self.plugins)} if self.plugins else {}
        extra |= {"rows": [str(r) for r in self.rows]} if self.rows else {}
        extra |= {"deep": [str(d) for d in self.deep]} if self.deep else {}
        return {**super().recorded(), **extra}


def specs(s: Settings) -> list[TrialSpec]:
    """Every episode: scenario by scenario, allocator by allocator, seed by seed (the suite's
    evaluation episodes, `tavc_agents.evaluation.episode_spec`)."""
    episode_h = None if s.episode_h is None else float(s.episode_h)
    out = []
    for name in s.scenarios:
        scenario = SCENARIOS[name]
        values = [c.value for c in scenario.config().circuits]
        model = load_model(scenario.model).with_values(values)
        for allocator in allocators(model, plugins=s.plugins, rich=True):
            for seed in s.seeds_of(scenario):
                spec = episode_spec(
                    name,
                    seed,
                    allocator.allocator,
                    allocator.kwargs,
                    episode_h,
                    allocator.observation_mode,
                )
                tags: dict[str, TagValue] = {
                    "scenario": name,
                    "allocator": allocator.name,
                    "seed": seed,
                }
                key = episode_key(name, allocator.name, seed)
                out.append(dataclasses.replace(spec, key=key, tags=tags))
    return out


def submitted_rows(s: Settings, refs: Mapping[str, Mapping[str, float]]) -> list[Row]:
    """The episodes of the submitted rows, scored with this leaderboard's references; a row that
    lacks an episode of this leaderboard (or was run with other episode lengths) is refused."""
    wanted = {(n, seed) for n in s.scenarios for seed in s.seeds_of(SCENARIOS[n])}
    rows = []
    for path in s.rows:
        row = read_row(path)
        if row["episode_h"] != s.episode_h:
            raise ValueError(
                f"rows: {path} was run with episode_h = {row['episode_h']}; allowed: this "
                f"leaderboard's ({s.episode_h})"
            )
        have = {(e["scenario"], e["seed"]): e for e in row["episodes"]}
        missing = sorted(wanted - set(have))
        if missing:
            raise ValueError(
                f"rows: {path} lacks episode {missing[0]} and {len(missing) - 1} more of this "
                "leaderboard; allowed: a row evaluated on the same scenarios and seeds"
            )
        for name, seed in sorted(wanted):
            value, ref = float(have[(name, seed)]["value_per_hour"]), refs[name]
            rows.append(
                {
                    "scenario": name,
                    "allocator": f"{row['name']}{SUBMITTED}",
                    "seed": seed,
                    "value_per_h": value,
                    "score": normalised(value, ref),
                    "wall_s": 0.0,
                }
            )
    return rows


@dataclass(frozen=True)
class DeepRow:
    """A deep learner of a `deep_leaderboard.py` report: its cells (scenario -> IQM over training
    seeds of each network's mean score, interval, read-out) and its training cost."""

    name: str
    cells: dict[str, tuple[float, float, float, str]]
    runs: int
    decisions_per_run: float
    cpu_h_per_run: float
    decisions_per_cpu_s: float


def deep_rows(s: Settings) -> list[DeepRow]:
    """The learners of every `--deep` folder, on this leaderboard's scenarios; a report scored on
    other episodes (seeds or length) than this leaderboard's is refused."""
    out = []
    for folder in map(Path, s.deep):
        report = read_report(folder / DEEP_REPORT)
        settings = report["metadata"]["settings"]
        if (settings["eval_seeds_text"], settings["episode_text"]) != (
            s.seeds_text,
            s.episode_text,
        ):
            raise ValueError(
                f"deep: {folder} was scored on {settings['eval_seeds_text']} evaluation seeds of "
                f"{settings['episode_text']} episodes; allowed: this leaderboard's "
                f"({s.seeds_text} of {s.episode_text})"
            )
        runs = list(read_csv(folder / "deep_leaderboard.csv"))
        for algorithm in settings["algorithms"]:
            cells = {
                name: (v["iqm"], v["ci"][0], v["ci"][1], v["readout"])
                for name in s.scenarios
                for v in [report["summary"].get(f"{name}/{algorithm}")]
                if v is not None
            }
            mine = [r for r in runs if r["algorithm"] == algorithm and r["scenario"] in cells]
            if not mine:
                continue
            decisions = float(np.mean([float(r["decisions"]) for r in mine]))
            train_cpu_s = float(np.mean([float(r["train_cpu_s"]) for r in mine]))
            out.append(
                DeepRow(
                    name=f"{algorithm} [{folder.name}]",
                    cells=cells,
                    runs=len(mine),
                    decisions_per_run=decisions,
                    cpu_h_per_run=float(np.mean([float(r["cpu_s"]) for r in mine])) / 3600.0,
                    decisions_per_cpu_s=decisions / train_cpu_s,
                )
            )
    return out


def deep_section(s: Settings, deep: Sequence[DeepRow]) -> str:
    """The deep learners' table beside the allocators', with what a cell means and what a run cost."""
    header = [
        "deep learner",
        *(SCENARIOS[n].id for n in s.scenarios),
        "runs",
        "decisions per run",
        "CPU h per run",
        "training decisions per CPU s",
    ]
    table = [
        [
            d.name,
            *(
                f"{c[0]:.2f} [{c[1]:.2f}, {c[2]:.2f}] ({c[3]})" if c else "-"
                for n in s.scenarios
                for c in [d.cells.get(n)]
            ),
            d.runs,
            f"{d.decisions_per_run:,.0f}",
            f"{d.cpu_h_per_run:.2f}",
            f"{d.decisions_per_cpu_s:,.0f}",
        ]
        for d in deep
    ]
    return (
        "\n\nDeep learners beside the allocators (`--deep`: reports of "
        "`benchmarks/deep_leaderboard.py`, networks trained offline and then scored on the same "
        "evaluation seeds and episode length): a cell is the interquartile mean over training "
        "seeds of each final network's mean normalised score over those seeds [95 % percentile "
        "bootstrap over training seeds], read out as named (the read-out the learner's own "
        "training-side episodes chose: `sampled` is the policy as it acts, `greedy` its argmax); "
        "- where it was not trained. Its variability is across training runs, the allocators' "
        "across episodes, so compare the points, and the intervals within a table. Cost: CPU "
        "time of a whole run (training, learning curve, its own evaluation), over the runs "
        "shown.\n\n" + markdown_table(header, table)
    )


def rows_of(
    specs_run: Sequence[TrialSpec],
    results: Mapping[str, TrialResult],
    refs: Mapping[str, Mapping[str, float]],
) -> list[Row]:
    rows = []
    for spec in specs_run:
        name, allocator = str(spec.tags["scenario"]), str(spec.tags["allocator"])
        value = value_per_hour(results[spec.key])
        ref = refs[name]
        rows.append(
            {
                "scenario": name,
                "allocator": allocator,
                "seed": spec.seed,
                "value_per_h": value,
                "score": normalised(value, ref),
                "wall_s": results[spec.key].wall_s,
            }
        )
    return rows


def report(s: Settings, rows: list[Row], deep: Sequence[DeepRow] = ()) -> Report:
    rng = np.random.default_rng(s.seed)
    names = list(dict.fromkeys(r["allocator"] for r in rows))
    cells: dict[tuple[str, str], tuple[float, float, float]] = {}
    summary: dict[str, Any] = {}
    for allocator in names:
        per_scenario = []
        for name in s.scenarios:
            scores = [
                r["score"] for r in rows if r["allocator"] == allocator and r["scenario"] == name
            ]
            per_scenario.append(scores)
            cells[(allocator, name)] = iqm_ci([scores], s.resamples, rng)
        cells[(allocator, "suite")] = iqm_ci(per_scenario, s.resamples, rng)
        summary[allocator] = {
            key: {"iqm": v[0], "ci": [v[1], v[2]]}
            for key, v in ((k, cells[(allocator, k)]) for k in (*s.scenarios, "suite"))
        }
    order = ranked(names, cells)

    def cell(v: tuple[float, float, float]) -> str:
        return f"{v[0]:.2f} [{v[1]:.2f}, {v[2]:.2f}]"

    header = ["allocator", *(SCENARIOS[n].id for n in s.scenarios), "suite (IQM, stratified)"]
    table = [[a, *(cell(cells[(a, n)]) for n in (*s.scenarios, "suite"))] for a in order]
    seeds = sorted({len(s.seeds_of(SCENARIOS[n])) for n in s.scenarios})
    run_here = [r for r in rows if not r["allocator"].endswith(SUBMITTED)]
    wall = sum(r["wall_s"] for r in run_here)
    body = (
        "Normalised score (0 = random allocation, 1 = the model optimum; the scenarios' committed "
        "references) of every allocator: interquartile mean over "
        f"{'/'.join(str(k) for k in seeds)} evaluation seeds per scenario [95 % percentile "
        f"bootstrap, {s.resamples} resamples; the suite's column resamples seeds within each "
        "scenario]. Allocators are sorted by the suite's IQM. The TAVC learners learn online "
        f"within each episode. {len(run_here)} episodes, {wall / 60:.1f} min of episode wall time "
        "in all (one process); a row marked submitted was evaluated elsewhere by "
        "`tavc evaluate` on the same episodes.\n\n" + markdown_table(header, table)
    )
    if deep:
        body += deep_section(s, deep)
        summary["deep"] = {
            d.name: {
                name: {"iqm": c[0], "ci": [c[1], c[2]], "readout": c[3]}
                for name, c in d.cells.items()
            }
            for d in deep
        }
    for path in s.rows:  # where each submitted row was computed, from the row itself
        row = read_row(path)
        body += (
            f"\n\nSubmitted row `{row['name']}` (`{Path(path).name}`), "
            f"{row['metadata'].get('evaluation_cpu_s', '?')} CPU s of evaluation:\n\n"
            + metadata_markdown(row["metadata"])
        )
    rep = Report(
        "leaderboard", "Leaderboard: every allocator on every scenario", body, rows, summary
    )
    for d in deep:
        cells.update({(d.name, n): c[:3] for n, c in d.cells.items()})
    shown = [*order, *(d.name for d in deep)]
    rep.figures.append((FIGURE, lambda path: draw(path, shown, s.scenarios, cells)))
    return rep


Cells = Mapping[tuple[str, str], tuple[float, float, float]]
"""(allocator, scenario or "suite") -> IQM, interval low, interval high"""


def ranked(names: Sequence[str], cells: Cells) -> list[str]:
    """The rows with a suite cell (the allocators), best suite IQM first (ties in `names`'
    order), then the others (the deep learners) in `names`' order."""
    suite = sorted(
        (a for a in names if (a, "suite") in cells), key=lambda a: -cells[(a, "suite")][0]
    )
    return suite + [a for a in names if (a, "suite") not in cells]


def cells_of(summary: Mapping[str, Mapping[str, Mapping[str, Any]]]) -> tuple[list[str], Cells]:
    """The scenarios and the cells of a written report's summary (`leaderboard.json`), for
    `--figure-only`: the numbers as the table reports them, nothing recomputed; the deep
    learners' cells (only on the scenarios they trained on) under their names too."""
    entries = {k: v for k, v in summary.items() if k != "deep"} | dict(summary.get("deep", {}))
    cells = {
        (row, key): (float(v["iqm"]), float(v["ci"][0]), float(v["ci"][1]))
        for row, entry in entries.items()
        for key, v in entry.items()
    }
    scenarios = [key for key in next(iter(summary.values())) if key != "suite"]
    return scenarios, cells


def draw(path: Path, order: Sequence[str], scenarios: Sequence[str], cells: Cells) -> None:
    """One panel per scenario and one for the suite, `PANELS_PER_ROW` to a row: each row's IQM
    with its interval, where it has one (a deep learner only on the scenarios it trained on, in
    another colour)."""
    keys = [*scenarios, "suite"]
    ncols = min(PANELS_PER_ROW, len(keys))
    nrows = math.ceil(len(keys) / ncols)
    fig, axes = subplots(
        nrows,
        ncols,
        figsize=(2.1 * ncols + 1.4, nrows * (0.28 * len(order) + 1.1) + 0.4),
        sharey=True,
        squeeze=False,
    )
    y = np.arange(len(order))
    panels = axes.ravel()
    for ax in panels[len(keys) :]:  # a last row left short
        ax.set_visible(False)
    for k, (ax, key) in enumerate(zip(panels, keys)):
        for rows, colour in (
            ([a for a in order if (a, "suite") in cells], "C0"),
            ([a for a in order if (a, "suite") not in cells], "C3"),
        ):
            have = [a for a in rows if (a, key) in cells]
            if not have:
                continue
            values = np.array([cells[(a, key)] for a in have])
            ax.errorbar(
                values[:, 0],
                [order.index(a) for a in have],
                xerr=[values[:, 0] - values[:, 1], values[:, 2] - values[:, 0]],
                fmt="o",
                ms=4,
                color=colour,
            )
        ax.axvline(0.0, color="grey", lw=0.5)
        ax.axvline(1.0, color="grey", lw=0.5, ls="--")
        title = "suite" if key == "suite" else SCENARIOS[key].id.removeprefix("tavc/")
        ax.set_title(title, fontsize=10)
        ax.tick_params(labelsize=9)
        if k % ncols == 0:
            ax.set_ylabel("allocator", fontsize=9)
        if k + ncols >= len(keys):  # the lowest panel of its column
            ax.set_xlabel("IQM score", fontsize=9)
    first = panels[0]  # the y axis is shared: its ticks are every panel's
    first.set_yticks(y, list(order))
    first.invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


def run(settings: Settings) -> Outcome:
    """Run (or resume) every episode, then write the table, the per-episode rows and the figure;
    with `figure_only`, only redraw the figure from the report in the output folder."""
    s = settings.sized()
    out = s.out_dir()
    if s.figure_only:
        summary = read_report(redraw_source(out / "leaderboard.json"))["summary"]
        scenarios, cells = cells_of(summary)
        order = ranked([k for k in summary if k != "deep"] + list(summary.get("deep", {})), cells)
        return redraw(out, FIGURE, lambda path: draw(path, order, scenarios, cells))
    refs = references(s.references)
    jobs = specs(s)
    deep = deep_rows(s)  # (read first: a refused folder stops the run before any episode)
    results, provenance = s.run_trials(jobs)
    rep = report(s, rows_of(jobs, results, refs) + submitted_rows(s, refs), deep)
    # the header names this command when every episode was resumed from a run of other settings
    # (other rows or deep reports): the table is this command's, the episodes are as they were
    same = provenance.get("settings") == s.recorded()
    written = rep.write(out, provenance if same else run_metadata(settings=s.recorded()))
    return Outcome(out, written, rep.body)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
