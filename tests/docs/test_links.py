"""Every relative link of the documentation points at a file of the repository.

Read: README.md, every page under docs/ and the files they include (see tests/docs/markdown.py).
A link is an inline link or image `[text](target)`, a reference definition `[label]: target`, or
an HTML `href` / `src`; links inside code (fenced blocks, inline code) are not links. URLs (with a
scheme) and in-page anchors are not checked; of a relative target, the anchor and query are
dropped and the path, resolved from the linking file's folder, must exist inside the repository.
Absolute paths are refused: the pages must read the same in a clone and on the site.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.docs.markdown import ROOT, documentation_files, fenced_blocks, snippet_targets, snippets

INLINE_CODE = re.compile(r"(`+)(?:(?!\1)[\s\S])+?\1")
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*(<[^>]*>|[^)\s]+)(?:\s+[^)]*)?\)")
REFERENCE = re.compile(r"^[ ]{0,3}\[[^\]]+\]:\s*(<[^>]*>|\S+)", re.MULTILINE)
HTML = re.compile(r"""\b(?:href|src)\s*=\s*["']([^"']+)["']""")
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")

FILES = documentation_files()


def link_targets(path: Path) -> list[tuple[int, str]]:
    """(line, target) of every link in a Markdown file, outside code."""
    _, prose = fenced_blocks(path)
    # Blank inline code, keeping its newlines (a code span may wrap).
    prose = INLINE_CODE.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), prose)
    found = []
    for pattern in (INLINE_LINK, REFERENCE, HTML):
        for match in pattern.finditer(prose):
            target = match.group(1).strip("<>")
            found.append((prose.count("\n", 0, match.start(1)) + 1, target))
    return sorted(found)


def broken_links(path: Path, root: Path = ROOT) -> list[str]:
    """What is wrong with the links of a Markdown file inside the repository `root`."""
    problems = []
    for line, target in link_targets(path):
        if SCHEME.match(target) or target.startswith("#"):
            continue
        where = f"{path.relative_to(root)}:{line}: {target}"
        relative = target.split("#", 1)[0].split("?", 1)[0]
        if relative.startswith("/"):
            problems.append(f"{where} (an absolute path; use a path relative to the file)")
            continue
        resolved = (path.parent / relative).resolve()
        if not resolved.is_relative_to(root):
            problems.append(f"{where} (leaves the repository)")
        elif not resolved.exists():
            problems.append(f"{where} (no such file)")
    return problems


def test_the_documentation_is_read() -> None:
    names = {p.relative_to(ROOT).as_posix() for p in FILES}
    assert {"README.md", "docs/index.md", "docs/env.md", "DESIGN.md"} <= names
    assert len(link_targets(ROOT / "README.md")) >= 10  # the reader finds the README's links


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_relative_link_points_at_a_file(path: Path) -> None:
    assert broken_links(path) == []


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_included_file_exists(path: Path) -> None:
    assert [t for t in snippet_targets(path) if not t.is_file()] == []


def unmarked_sections(path: Path) -> list[str]:
    """The sections a page includes (`--8<-- "FILE:SECTION"`) that their file does not mark
    exactly once with `--8<-- [start:SECTION]` ... `--8<-- [end:SECTION]`, in that order."""
    problems = []
    for file, section in snippets(path):
        if section is None or not file.is_file():
            continue
        text = file.read_text(encoding="utf-8")
        start, end = f"--8<-- [start:{section}]", f"--8<-- [end:{section}]"
        if text.count(start) != 1 or text.count(end) != 1 or text.find(start) > text.find(end):
            problems.append(f"{file.name}:{section}")
    return problems


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_included_section_is_marked(path: Path) -> None:
    assert unmarked_sections(path) == []


def test_the_home_page_includes_the_readme(tmp_path: Path) -> None:
    """The home page takes the README's opening, commands and tested example by section, so the
    two cannot drift apart; a section named but not marked is found."""
    home = ROOT / "docs" / "index.md"
    wanted = {(ROOT / "README.md", section) for section in ("intro", "commands", "example")}
    assert wanted <= set(snippets(home))
    page = tmp_path / "page.md"
    page.write_text('--8<-- "README.md:intro"\n--8<-- "README.md:no_such_section"\n', "utf-8")
    assert unmarked_sections(page) == ["README.md:no_such_section"]


def test_a_broken_link_is_found(tmp_path: Path) -> None:
    """The checker itself: a missing target is reported, code and URLs are not links."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "index.md").write_text("# index\n", encoding="utf-8")
    (tmp_path / "frame.png").write_bytes(b"")
    page = tmp_path / "docs" / "page.md"
    page.write_text(
        "[ok](index.md) [gone](nowhere.md#x) ![img](../frame.png)\n"
        "`[code](not-a-link.md)` [web](https://example.org/x.md) [here](#anchor)\n"
        "```python\n# [in a block](nor-this.md)\n```\n"
        "[ref]: missing/ref.md\n"
        '<img src="also-missing.png"> [up](../../outside.md) [abs](/docs/index.md)\n',
        encoding="utf-8",
    )
    assert [p.split(": ", 1)[1] for p in broken_links(page, root=tmp_path)] == [
        "nowhere.md#x (no such file)",
        "missing/ref.md (no such file)",
        "../../outside.md (leaves the repository)",
        "/docs/index.md (an absolute path; use a path relative to the file)",
        "also-missing.png (no such file)",
    ]
