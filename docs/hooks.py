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

A page that includes a committed report through pymdownx.snippets
(`--8<-- "benchmarks/results/leaderboard/leaderboard.md"` on a line of its own) gets the report
expanded here, before snippets (a Markdown preprocessor, run after this hook) sees the line, and
reshaped for reading inside the page: without its `# Title` (the page's section heading stands for
it; the report's own `##` headings move down below that section's level), its body as written,
then its provenance bullets (`- Command: ...`, `- Machine: ...`, ...) in a collapsed
`??? info "How these numbers were computed"` block (pymdownx.details) at the end. The report's
links are resolved from its own folder, as in the repository. The committed file is not changed,
and a report published as a page of its own keeps its title and its provenance on top.

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
# A line of pymdownx.snippets that includes one file: --8<-- "path" (or 'path'). The hook expands
# it when the path is a committed Markdown report (a path with a section or line numbers, `:` and
# after, is not one, and is left to snippets).
INCLUDE = re.compile(
    r"""^(?P<indent>[ \t]*)--8<--[ \t]+(?P<quote>["'])(?P<path>[^"'\n]+)(?P=quote)[ \t]*$""",
    re.MULTILINE,
)
# An ATX heading (`## Method`): its hashes.
HEADING = re.compile(r"^(?P<hashes>#{1,6})(?=[ \t]|$)", re.MULTILINE)
# A provenance line of a report (agents/tavc_agents/analysis/reports.py, metadata_markdown).
PROVENANCE = re.compile(r"^- [A-Z][^:\n]*: ")
PROVENANCE_SUMMARY = "How these numbers were computed"


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
    # The reports the pages link to, then the reports those link to, until none is new. A report a
    # page includes is part of that page: what it links to is published, the report itself not.
    pending = [Path(f.abs_src_path) for f in files.documentation_pages() if f.abs_src_path]
    scanned: set[Path] = set()
    while pending:
        source = pending.pop().resolve()
        if source in scanned:
            continue
        scanned.add(source)
        markdown = source.read_text(encoding="utf-8")
        for repo_path in linked_reports(markdown, source.parent, docs, root):
            if files.get_file_from_path(repo_path) is None:
                _add(files, repo_path, root, config)
                if repo_path.endswith(".md"):
                    pending.append(root / repo_path)
        pending.extend(root / repo_path for repo_path in included_reports(markdown, root))
    return files


class _Site:
    """What rendering a page's Markdown needs: the repository, docs/, the page and the files."""

    def __init__(self, root: Path, docs: Path, page_uri: str, files: Files) -> None:
        self.root, self.docs, self.page_uri, self.files = root, docs, page_uri, files


def _rewrite(text: str, source_dir: Path, site: _Site) -> str:
    """The links of Markdown from `source_dir` that leave docs/, as the page shows them."""

    def rewrite(match: re.Match[str]) -> str:
        if match.group("code"):
            return match.group(0)
        repo_path = _repo_target(match.group("target"), source_dir, site.docs, site.root)
        if repo_path is None:
            return match.group(0)
        if site.files.get_file_from_path(repo_path) is not None:  # published: link to it there
            site_target = posixpath.relpath(repo_path, posixpath.dirname(site.page_uri) or ".")
            return (
                f"{match.group('bang')}[{match.group('text')}]({site_target}{match.group('rest')})"
            )
        label = match.group("text")
        return f"`{repo_path}`" if label.strip("`") == repo_path else f"{label}: `{repo_path}`"

    return TOKEN.sub(rewrite, text)


def included_reports(markdown: str, root: Path) -> list[str]:
    """The repository paths of the committed reports a page includes (outside its code blocks)."""
    return [
        match.group("path")
        for piece in _outside_code(markdown)
        for match in INCLUDE.finditer(piece)
        if _is_report(match.group("path"), root)
    ]


def _is_report(path: str, root: Path) -> bool:
    """Whether an included path is a committed Markdown report that exists (a missing one is left
    to snippets, which names it)."""
    return path.startswith(RESULTS + "/") and path.endswith(".md") and (root / path).is_file()


def split_report(markdown: str) -> tuple[str, list[str], str]:
    """A report's title, provenance lines and body: `# Title`, then the paragraph of `- Key: value`
    bullets that reports.metadata_markdown writes, then the rest. A report without that paragraph
    has no provenance lines; one without a `# ` first line has the title ""."""
    lines = markdown.splitlines()
    title = ""
    if lines and lines[0].startswith("# "):
        title, lines = lines[0][2:].strip(), lines[1:]
    while lines and not lines[0].strip():
        lines = lines[1:]
    end = next((i for i, line in enumerate(lines) if not line.strip()), len(lines))
    provenance = lines[:end]
    if not provenance or not all(PROVENANCE.match(line) for line in provenance):
        provenance, end = [], 0
    return title, provenance, "\n".join(lines[end:]).strip("\n")


def _indent(text: str, prefix: str) -> str:
    return "\n".join(prefix + line if line.strip() else "" for line in text.split("\n"))


def _include(repo_path: str, indent: str, section: int, site: _Site, seen: tuple[str, ...]) -> str:
    """A report as a page shows it in place of the snippets line that includes it: its body (its
    headings moved below the including section's level), then its provenance, collapsed."""
    source = site.root / repo_path
    _, provenance, body = split_report(source.read_text(encoding="utf-8"))
    seen = (*seen, repo_path)
    text = _render(body, source.parent, site, demote=max(section - 1, 0), seen=seen)
    if provenance:
        lines = _rewrite("\n".join(provenance), source.parent, site)
        text += f'\n\n??? info "{PROVENANCE_SUMMARY}"\n\n' + _indent(lines, "    ")
    return _indent(text, indent) + "\n"


def _render(
    markdown: str, source_dir: Path, site: _Site, demote: int = 0, seen: tuple[str, ...] = ()
) -> str:
    """Markdown from `source_dir` (a page, or a report it includes) as the site shows it: links
    out of docs/ rewritten, included reports expanded, `no-run` marks dropped; its headings moved
    down `demote` levels."""
    pieces = FENCED.split(markdown)  # even pieces lie outside fenced code blocks, odd ones inside
    out = []
    section = 1  # the level of the last heading seen, the including section of a report
    for i, piece in enumerate(pieces):
        if i % 2:
            out.append(NO_RUN.sub(r"\1", piece))
            continue
        if demote:
            piece = HEADING.sub(lambda m: "#" * min(len(m.group("hashes")) + demote, 6), piece)
        start = 0
        for match in INCLUDE.finditer(piece):
            repo_path = match.group("path")
            if not _is_report(repo_path, site.root) or repo_path in seen:
                continue
            before = piece[start : match.start()]
            section = max((len(h) for h in HEADING.findall(before)[-1:]), default=section)
            out.append(_rewrite(before, source_dir, site))
            out.append(_include(repo_path, match.group("indent"), section, site, seen))
            start = match.end()
        rest = piece[start:]
        section = max((len(h) for h in HEADING.findall(rest)[-1:]), default=section)
        out.append(_rewrite(rest, source_dir, site))
    return "".join(out)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    site = _Site(_root(config), Path(config.docs_dir).resolve(), page.file.src_uri, files)
    return _render(markdown, Path(page.file.abs_src_path).resolve().parent, site)
