"""The Markdown of the documentation, read for the docs tests: README.md, every page under docs/
and the files the pages include (`--8<-- "DESIGN.md"`, or a marked section of one,
`--8<-- "README.md:example"`: pymdownx.snippets, paths from the repository root), with their fenced
code blocks."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SNIPPET = re.compile(r"""^\s*--8<--\s+["']([^"']+)["']\s*$""", re.MULTILINE)
OPENING = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>.*)$")


@dataclass(frozen=True)
class Block:
    """A fenced code block: its file, the line of its opening fence (from 1), its info string
    (`python`, `python no-run`, `bash`, ...) and its text, unindented by the fence's indent."""

    path: Path
    line: int
    info: str
    code: str

    @property
    def language(self) -> str:
        return self.info.split()[0] if self.info else ""

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def snippets(path: Path) -> list[tuple[Path, str | None]]:
    """What a page includes with pymdownx.snippets: (file, section or None) for every
    `--8<-- "FILE"` or `--8<-- "FILE:SECTION"` line (paths from the repository root)."""
    found = []
    for name in SNIPPET.findall(path.read_text(encoding="utf-8")):
        file, _, section = name.partition(":")
        found.append((ROOT / file, section or None))
    return found


def snippet_targets(path: Path) -> list[Path]:
    """The files a page includes with pymdownx.snippets (paths from the repository root)."""
    return [file for file, _ in snippets(path)]


def documentation_files() -> list[Path]:
    """README.md, every Markdown page under docs/, and the files those pages include."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    included = [t for p in pages for t in snippet_targets(p) if t.suffix == ".md" and t.is_file()]
    return list(dict.fromkeys([*pages, *included]))


def fenced_blocks(path: Path) -> tuple[list[Block], str]:
    """The fenced code blocks of a Markdown file, and its text with every fenced block (fences
    included) blanked out line for line, so that line numbers stay right."""
    lines = path.read_text(encoding="utf-8").split("\n")
    blocks: list[Block] = []
    prose = list(lines)
    i = 0
    while i < len(lines):
        opening = OPENING.match(lines[i])
        if opening is None or (opening["fence"][0] == "`" and "`" in opening["info"]):
            i += 1
            continue
        indent, fence = opening["indent"], opening["fence"]
        closing = re.compile(rf"^[ \t]*{re.escape(fence[0])}{{{len(fence)},}}[ \t]*$")
        end = i + 1
        while end < len(lines) and not closing.match(lines[end]):
            end += 1
        body = [ln[len(indent) :] if ln.startswith(indent) else ln for ln in lines[i + 1 : end]]
        blocks.append(Block(path, i + 1, opening["info"].strip(), "\n".join(body) + "\n"))
        for k in range(i, min(end + 1, len(lines))):
            prose[k] = ""
        i = end + 1
    return blocks, "\n".join(prose)
