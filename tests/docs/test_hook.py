"""The docs hook (docs/hooks.py) publishes what the pages link to outside docs/.

A small project is built with the hook, strict, as `mkdocs build --strict` builds the real site:
a page links to a committed report (Markdown), a table (CSV) and a figure under
`benchmarks/results/`, and to a source file the site does not carry. The report's link must
resolve to a page of the site (rendered, with the report's own figure and its link to a second
report working too), the table and the figure must be files of the site, and the source file must
be shown as its repository path, not as a dead link. A `python no-run` block stays a code block.

A page that includes a committed report through pymdownx.snippets shows it without its title, its
provenance collapsed in a `<details>` block after its body; the same report opened as its own page
keeps both on top. The real pages' includes are ones the hook expands, and the real site's
stylesheet keeps the first column of a wide table in view.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from types import ModuleType

import pytest
import yaml

# The docs extra (mkdocs and its plugins) is not in `dev`: without it this module skips, naming it
pytest.importorskip(
    "mkdocs", reason="the docs hook test needs the docs extra: pip install -e '.[docs]'"
)
pytest.importorskip(
    "pymdownx", reason="the docs hook test needs the docs extra: pip install -e '.[docs]'"
)

from mkdocs.commands.build import build
from mkdocs.config import load_config

from tests.docs.markdown import ROOT

HOOK = ROOT / "docs" / "hooks.py"


def _hook() -> ModuleType:
    spec = importlib.util.spec_from_file_location("docs_hooks", HOOK)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


def _hrefs(html: str) -> list[str]:
    return re.findall(r'(?:href|src)="([^"#]+)', html)


def _main(html: str) -> str:
    """The page's content in the mkdocs theme's HTML, without the navigation around it."""
    return html[html.index('role="main"') : html.index("<footer")]


def test_report_links_resolve_on_the_built_site(tmp_path: Path) -> None:
    _write(
        tmp_path / "mkdocs.yml",
        f"site_name: t\ndocs_dir: docs\nuse_directory_urls: false\nhooks:\n  - {HOOK}\n"
        "validation:\n  links:\n    not_found: warn\n    unrecognized_links: warn\n"
        "markdown_extensions:\n  - pymdownx.superfences\n",
    )
    _write(
        tmp_path / "docs" / "index.md",
        "# Home\n\n"
        "See [the report](../benchmarks/results/study/report.md),\n"
        "[the table](../benchmarks/results/study/trials.csv) and the\n"
        "[code](../src/model.py).\n\n"
        "![the figure](../benchmarks/results/study/figure.png)\n\n"
        "`[not a link](../benchmarks/results/study/unlinked.md)`\n\n"
        "```python no-run\nimport not_run\n```\n",
    )
    study = tmp_path / "benchmarks" / "results" / "study"
    _write(study / "report.md", "# Report\n\n![fig](figure.png) [details](details.md)\n")
    _write(study / "details.md", "# Details\n")
    _write(study / "unlinked.md", "# Never linked\n")
    _write(study / "trials.csv", "seed,value\n0,1.5\n")
    (study / "figure.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    _write(tmp_path / "src" / "model.py", "x = 1\n")

    site = tmp_path / "site"
    build(load_config(str(tmp_path / "mkdocs.yml"), site_dir=str(site), strict=True))

    home = (site / "index.html").read_text(encoding="utf-8")
    links = _hrefs(home)
    for target in (
        "benchmarks/results/study/report.html",
        "benchmarks/results/study/trials.csv",
        "benchmarks/results/study/figure.png",
    ):
        assert target in links
        assert (site / target).is_file()
    # The report is a page of the site: rendered, its figure and its own report link work.
    report = (site / "benchmarks/results/study/report.html").read_text(encoding="utf-8")
    assert "<h1" in report and "Report" in report
    assert {"figure.png", "details.html"} <= set(_hrefs(report))
    assert (site / "benchmarks/results/study/details.html").is_file()
    # Only what a page links to is published; what the site does not carry is named, not linked.
    assert not (site / "benchmarks/results/study/unlinked.html").exists()
    assert "<code>src/model.py</code>" in home
    # A block the tests only compile is still a code block, not text with its fences.
    assert "no-run" not in home and "```" not in home
    assert re.search(r"<code[^>]*>(?:(?!</code>).)*not_run", home, re.DOTALL)
    assert "model.py" not in " ".join(links)


REPORT = """# Board: every allocator

- Generated: 2026-01-01T00:00:00+00:00
- Command: `python benchmarks/board.py --update-reference`
- Machine: Linux; AMD EPYC; 2 cores; 23.5 GiB RAM

Normalised score of every allocator ([the trials](board.csv)).

| allocator | tavc/dahl2004-v0 | suite (IQM, stratified) |
|---|---|---|
| static | 0.99 [0.99, 0.99] | 0.93 [0.93, 0.93] |

## Method

Interquartile means over 20 seeds.
"""


def test_an_included_report_loses_its_title_and_folds_its_provenance(tmp_path: Path) -> None:
    _write(
        tmp_path / "mkdocs.yml",
        f"site_name: t\ndocs_dir: docs\nuse_directory_urls: false\nhooks:\n  - {HOOK}\n"
        "validation:\n  links:\n    not_found: warn\n    unrecognized_links: warn\n"
        "markdown_extensions:\n  - admonition\n  - pymdownx.details\n  - pymdownx.superfences\n"
        f"  - pymdownx.snippets:\n      base_path: ['{tmp_path}']\n      check_paths: true\n",
    )
    _write(
        tmp_path / "docs" / "results" / "page.md",
        "# Page\n\n## The leaderboard\n\nEvery allocator on every scenario.\n\n"
        '--8<-- "benchmarks/results/board/board.md"\n\n'
        "After the report. [The report on its own](../../benchmarks/results/board/board.md).\n",
    )
    board = tmp_path / "benchmarks" / "results" / "board"
    _write(board / "board.md", REPORT)
    _write(board / "board.csv", "allocator,score\nstatic,0.99\n")

    site = tmp_path / "site"
    build(load_config(str(tmp_path / "mkdocs.yml"), site_dir=str(site), strict=True))

    page = (site / "results" / "page.html").read_text(encoding="utf-8")
    article = _main(page)
    # One title: the page's. The report's `##` sits below the page's section that includes it.
    assert len(re.findall(r"<h1", article)) == 1 and "Board: every allocator" not in page
    assert re.search(r'<h3 id="method"', article)
    # The body as written, the table whole, then the provenance folded in a details block.
    table = article.index("<table>")
    assert "<td>static</td>" in article and "suite (IQM, stratified)" in article
    details = re.findall(r"<details[^>]*>(.*?)</details>", article, re.DOTALL)
    assert len(details) == 1
    assert "<summary>How these numbers were computed</summary>" in details[0]
    for line in ("Generated: 2026-01-01", "python benchmarks/board.py", "Machine: Linux"):
        assert article.count(line) == 1 and line in details[0]
    assert table < article.index("<details") < article.index("After the report.")
    assert article.index("Interquartile means") < article.index("<details")
    # The report's link, relative to its own folder, reaches its CSV in the site.
    assert "../benchmarks/results/board/board.csv" in _hrefs(article)
    assert (site / "benchmarks/results/board/board.csv").is_file()

    # Opened as its own page, the report keeps its title and its provenance on top.
    own = (site / "benchmarks/results/board/board.html").read_text(encoding="utf-8")
    own = _main(own)
    assert re.search(r"<h1[^>]*>Board: every allocator", own)
    assert "<details" not in own and own.index("Machine: Linux") < own.index("<table>")
    # The committed report is read, never written.
    assert (board / "board.md").read_text(encoding="utf-8") == REPORT


def test_split_report() -> None:
    hook = _hook()
    title, provenance, body = hook.split_report(REPORT)
    assert title == "Board: every allocator"
    assert [line.split(":")[0] for line in provenance] == ["- Generated", "- Command", "- Machine"]
    assert body.startswith("Normalised score") and body.endswith("20 seeds.")
    # A report whose first paragraph is not provenance keeps it in its body.
    title, provenance, body = hook.split_report("# Cell\n\nRan `x`: **ok**.\n\n- a: b\n")
    assert (title, provenance, body) == ("Cell", [], "Ran `x`: **ok**.\n\n- a: b")


def test_every_report_the_pages_include_is_expanded_by_the_hook() -> None:
    """Every `--8<--` line of a page that names a committed report is one the hook expands (not
    left to snippets, which would show the report's title and provenance mid-page), and each of
    those reports has the provenance the hook folds away."""
    hook = _hook()
    snippet = re.compile(r"""^\s*--8<--\s+["']([^"']+)["']\s*$""", re.MULTILINE)
    for page in (ROOT / "docs").rglob("*.md"):
        markdown = page.read_text(encoding="utf-8")
        reports = [p for p in snippet.findall(markdown) if p.startswith("benchmarks/results/")]
        assert hook.included_reports(markdown, ROOT) == reports, page
        for report in reports:
            _, provenance, _ = hook.split_report((ROOT / report).read_text(encoding="utf-8"))
            assert any(line.startswith("- Command:") for line in provenance), report


def _css_rules(css: str) -> list[tuple[str, dict[str, str]]]:
    """The innermost rules of a stylesheet (inside @media too): selector and declarations."""
    css = re.sub(r"/\*.*?\*/", "", css, flags=re.DOTALL)
    rules = []
    for selector, body in re.findall(r"([^{}]+)\{([^{}]*)\}", css):
        declarations = dict(
            (name.strip(), value.strip())
            for name, _, value in (d.partition(":") for d in body.split(";") if ":" in d)
        )
        rules.append((" ".join(selector.split()), declarations))
    return rules


def test_the_site_keeps_the_first_column_of_a_wide_table_in_view() -> None:
    """The site's stylesheets (mkdocs.yml extra_css) make a table's first cells sticky at the left
    edge, opaque, and keep the table from clipping them (Material gives tables `overflow: hidden`;
    a sticky cell inside an element that clips sticks to it, which does not scroll)."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    rules = [
        rule
        for sheet in config["extra_css"]
        for rule in _css_rules((ROOT / "docs" / sheet).read_text(encoding="utf-8"))
    ]
    sticky = [d for selector, d in rules if "td:first-child" in selector]
    assert any(
        d.get("position") == "sticky"
        and d.get("left") == "0"
        and d.get("background-color") == "var(--md-default-bg-color)"
        for d in sticky
    ), sticky
    assert any(
        "md-typeset__table table" in selector and d.get("overflow") == "visible"
        for selector, d in rules
    )
