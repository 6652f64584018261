"""The docs hook (docs/hooks.py) publishes what the pages link to outside docs/.

A small project is built with the hook, strict, as `mkdocs build --strict` builds the real site:
a page links to a committed report (Markdown), a table (CSV) and a figure under
`benchmarks/results/`, and to a source file the site does not carry. The report's link must
resolve to a page of the site (rendered, with the report's own figure and its link to a second
report working too), the table and the figure must be files of the site, and the source file must
be shown as its repository path, not as a dead link. A `python no-run` block stays a code block.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

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


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


def _hrefs(html: str) -> list[str]:
    return re.findall(r'(?:href|src)="([^"#]+)', html)


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
