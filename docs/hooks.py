"""MkDocs hook (mkdocs.yml `hooks:`): links from the pages to files of the repository outside docs/.

The pages under docs/ link to the committed results by their path in the repository, relative to
the page (`../../benchmarks/results/interference.png` from `docs/results/interference.md`), so that
every link works where the Markdown is read in the repository and `tests/docs/test_links.py` can
check that its target exists. The site serves only what is under docs/, so at build time:

- the committed figures (every PNG under `benchmarks/results/`) are copied into the site at the
  same path, and links to them are pointed there;
- any other link that leaves docs/ (a Markdown report, a CSV, a folder) is shown as its text and
  the target's repository path in a code span, since the site does not carry it.

Fenced code blocks and inline code are left alone.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

FIGURES = "benchmarks/results"
# Inline code (left alone), or a Markdown link or image whose target has no spaces:
# ![text](target "title"). Code comes first so that a link inside code is not taken for one.
TOKEN = re.compile(
    r"(?P<code>(?P<ticks>`+).+?(?P=ticks))"
    r"|(?P<bang>!?)\[(?P<text>[^\]]*)\]\((?P<target>[^)\s#]+)(?P<rest>[^)]*)\)"
)
# A fenced code block, from its opening fence to its closing one.
FENCED = re.compile(r"(^[ \t]*(?:```|~~~).*\n[\s\S]*?^[ \t]*(?:```|~~~)[ \t]*$)", re.MULTILINE)


def _root(config: Any) -> Path:
    return Path(config.config_file_path).resolve().parent


def on_files(files: Files, config: Any) -> Files:
    root = _root(config)
    for png in sorted((root / FIGURES).rglob("*.png")):
        files.append(
            File(
                png.relative_to(root).as_posix(),
                src_dir=str(root),
                dest_dir=config.site_dir,
                use_directory_urls=config.use_directory_urls,
            )
        )
    return files


def _rewrite(text: str, page_dir: Path, docs: Path, root: Path, page_uri: str) -> str:
    def rewrite(match: re.Match[str]) -> str:
        target = match.group("target")
        if match.group("code") or re.match(r"^[a-z][a-z0-9+.-]*:", target) or target[0] == "/":
            return match.group(0)  # code, a URL or an absolute path: not ours
        resolved = (page_dir / target).resolve()
        if resolved.is_relative_to(docs) or not resolved.is_relative_to(root):
            return match.group(0)  # inside docs/: MkDocs checks it
        repo_path = resolved.relative_to(root).as_posix() + ("/" if target.endswith("/") else "")
        if repo_path.startswith(FIGURES + "/") and repo_path.endswith(".png"):
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
        pieces[i] = _rewrite(pieces[i], page_dir, docs, root, page.file.src_uri)
    return "".join(pieces)
