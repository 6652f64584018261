"""MkDocs hook (mkdocs.yml `hooks:`): links from the pages to files of the repository outside docs/.

The pages under docs/ link to the committed results by their path in the repository, relative to
the page (`../../benchmarks/results/interference.png` from `docs/results/interference.md`), so that
every link works where the Markdown is read in the repository and `tests/docs/test_links.py` can
check that its target exists. The site serves only what is under docs/, so at build time:

- the committed figures (every PNG under `benchmarks/results/`) are published in the site at the
  same path, and links to them are pointed there;
- every committed report a page links to (a `.md`, `.csv` or `.txt` under `benchmarks/results/`)
  is published too: a Markdown report as a page of the site (outside the navigation), a table or
  text file as itself. Reports that a published report links to are published as well;
- any other link that leaves docs/ (a folder, a source file) is shown as its text and the
  target's repository path in a code span, since the site does not carry it.

Nothing is copied into docs/: the files are read from where they are committed. Fenced code
blocks and inline code are left alone, except that the docs tests' `no-run` mark on a fence
(```` ```python no-run ````, pseudo-code the tests only compile) is dropped: pymdownx.superfences
does not take a fence whose info string has a bare word after the language, and would show the
block as text.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files, InclusionLevel

RESULTS = "benchmarks/results"
FIGURES = (".png",)
REPORTS = (".md", ".csv", ".txt")
# Inline code (left alone), or a Markdown link or image whose target has no spaces:
# ![text](target "title"). Code comes first so that a link inside code is not taken for one.
TOKEN = re.compile(
    r"(?P<code>(?P<ticks>`+).+?(?P=ticks))"
    r"|(?P<bang>!?)\[(?P<text>[^\]]*)\]\((?P<target>[^)\s#]+)(?P<rest>[^)]*)\)"
)
# A fenced code block, from its opening fence to its closing one.
FENCED = re.compile(r"(^[ \t]*(?:```|~~~).*\n[\s\S]*?^[ \t]*(?:```|~~~)[ \t]*$)", re.MULTILINE)
SCHEME = re.compile(r"^[a-z][a-z0-9+.-]*:")
# The opening fence of a block the docs tests only compile (tests/docs/test_code_blocks.py).
NO_RUN = re.compile(r"\A([ \t]*(?:```|~~~)[\w+-]+)[ \t]+no-run[ \t]*$", re.MULTILINE)


def _root(config: Any) -> Path:
    return Path(config.config_file_path).resolve().parent


def _outside_code(markdown: str) -> list[str]:
    """The pieces of a page that lie outside its fenced code blocks."""
    return FENCED.split(markdown)[::2]


def _published(repo_path: str) -> bool:
    """Whether a repository path is one the site carries (a figure or a report of the results)."""
    return repo_path.startswith(RESULTS + "/") and repo_path.endswith(FIGURES + REPORTS)


def _repo_target(target: str, page_dir: Path, docs: Path, root: Path) -> str | None:
    """The repository path a link of a page points at, if it leaves docs/ for a place inside the
    repository; None for a URL, an absolute path, a link inside docs/ (MkDocs checks those) or one
    that leaves the repository."""
    if SCHEME.match(target) or target[0] == "/":
        return None
    resolved = (page_dir / target).resolve()
    if resolved.is_relative_to(docs) or not resolved.is_relative_to(root):
        return None
    return resolved.relative_to(root).as_posix() + ("/" if target.endswith("/") else "")


def linked_reports(markdown: str, page_dir: Path, docs: Path, root: Path) -> list[str]:
    """The repository paths of the committed results (figures and reports) a page links to."""
    found = []
    for piece in _outside_code(markdown):
        for match in TOKEN.finditer(piece):
            if match.group("code"):
                continue
            repo_path = _repo_target(match.group("target"), page_dir, docs, root)
            if repo_path and _published(repo_path) and (root / repo_path).is_file():
                found.append(repo_path)
    return found


def _add(files: Files, repo_path: str, root: Path, config: Any) -> None:
    page = repo_path.endswith(".md")
    files.append(
        File(
            repo_path,
            src_dir=str(root),
            dest_dir=config.site_dir,
            use_directory_urls=config.use_directory_urls,
            # A report is a page of the site, reached by its links, not from the navigation.
            inclusion=InclusionLevel.NOT_IN_NAV if page else InclusionLevel.UNDEFINED,
        )
    )


def on_files(files: Files, config: Any) -> Files:
    root = _root(config)
    docs = Path(config.docs_dir).resolve()
    for png in sorted((root / RESULTS).rglob("*.png")):
        _add(files, png.relative_to(root).as_posix(), root, config)
    # The reports the pages link to, then the reports those link to, until none is new.
    pending = [Path(f.abs_src_path) for f in files.documentation_pages() if f.abs_src_path]
    while pending:
        source = pending.pop()
        markdown = source.read_text(encoding="utf-8")
        for repo_path in linked_reports(markdown, source.resolve().parent, docs, root):
            if files.get_file_from_path(repo_path) is None:
                _add(files, repo_path, root, config)
                if repo_path.endswith(".md"):
                    pending.append(root / repo_path)
    return files


def _rewrite(text: str, page_dir: Path, docs: Path, root: Path, page_uri: str, files: Files) -> str:
    def rewrite(match: re.Match[str]) -> str:
        if match.group("code"):
            return match.group(0)
        repo_path = _repo_target(match.group("target"), page_dir, docs, root)
        if repo_path is None:
            return match.group(0)
        if files.get_file_from_path(repo_path) is not None:  # published: link to it in the site
            site_target = posixpath.relpath(repo_path, posixpath.dirname(page_uri) or ".")
            return (
                f"{match.group('bang')}[{match.group('text')}]({site_target}{match.group('rest')})"
            )
        label = match.group("text")
        return f"`{repo_path}`" if label.strip("`") == repo_path else f"{label}: `{repo_path}`"

    return TOKEN.sub(rewrite, text)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    root = _root(config)
    docs = Path(config.docs_dir).resolve()
    page_dir = Path(page.file.abs_src_path).resolve().parent
    # Even pieces lie outside fenced code blocks, odd ones inside.
    pieces = FENCED.split(markdown)
    for i in range(0, len(pieces), 2):
        pieces[i] = _rewrite(pieces[i], page_dir, docs, root, page.file.src_uri, files)
    for i in range(1, len(pieces), 2):
        pieces[i] = NO_RUN.sub(r"\1", pieces[i])
    return "".join(pieces)
