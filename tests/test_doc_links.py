"""Every relative link in README.md, docs/*.md and scenes/FORMAT.md resolves.

A link names a file that exists, and where it names an anchor (`page.md#a-heading`, or `#a-heading`
within the page) that page has a heading whose GitHub anchor is exactly that. Web addresses are
not followed. Run as a script (`python tests/test_doc_links.py`) it prints every broken link.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

FENCE = re.compile(r"^\s*(```|~~~)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
INLINE_CODE = re.compile(r"`[^`\n]*`")
HTML_ANCHOR = re.compile(r"<a\s+(?:name|id)=\"([^\"]+)\"")


def pages(root: Path = ROOT) -> list[Path]:
    """The documentation whose links are checked."""
    found = [root / "README.md", root / "scenes" / "FORMAT.md"]
    found += sorted((root / "docs").glob("*.md"))
    return [p for p in found if p.is_file()]


def prose_lines(text: str) -> list[tuple[int, str]]:
    """The page's lines outside fenced code blocks, numbered from 1."""
    out: list[tuple[int, str]] = []
    fenced = False
    for number, line in enumerate(text.splitlines(), start=1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            out.append((number, line))
    return out


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces as hyphens."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link's words only
    text = text.replace("`", "").lower()
    text = "".join(ch for ch in text if ch.isalnum() or ch in " -_")
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every anchor a page offers: its headings' (repeats numbered as GitHub does) and `<a id>`."""
    seen: dict[str, int] = {}
    out: set[str] = set()
    for _, line in prose_lines(page.read_text(encoding="utf-8")):
        out.update(HTML_ANCHOR.findall(line))
        match = HEADING.match(line)
        if not match:
            continue
        base = slug(match.group(2))
        count = seen.get(base, 0)
        seen[base] = count + 1
        out.add(base if count == 0 else f"{base}-{count}")
    return out


def broken_links(root: Path = ROOT) -> list[str]:
    """One line per link that does not resolve: page, line, the link, and what is wrong."""
    problems: list[str] = []
    cache: dict[Path, set[str]] = {}
    for page in pages(root):
        for number, line in prose_lines(page.read_text(encoding="utf-8")):
            for target in LINK.findall(INLINE_CODE.sub("", line)):
                if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
                    continue
                path_part, _, anchor = target.partition("#")
                where = f"{page.relative_to(root)}:{number}: ({target})"
                dest = (page.parent / path_part).resolve() if path_part else page
                if not dest.exists():
                    problems.append(f"{where} names a file that does not exist")
                    continue
                if not anchor:
                    continue
                if dest.suffix != ".md":
                    problems.append(f"{where} has an anchor, but is not a Markdown page")
                    continue
                if dest not in cache:
                    cache[dest] = anchors(dest)
                if anchor not in cache[dest]:
                    problems.append(f"{where} names a heading {dest.name} does not have")
    return problems


def test_every_relative_link_resolves() -> None:
    assert broken_links() == []


def test_the_check_finds_a_missing_file_and_a_missing_heading(tmp_path: Path) -> None:
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text(
        "# Page A\n\n## Calibration (paper §2)\n\n## Calibration (paper §2)\n\n"
        "```sh\n# not a heading\n[in code](gone.md)\n```\n",
        encoding="utf-8",
    )
    (tmp_path / "README.md").write_text(
        "[good](docs/a.md#calibration-paper-2) [repeat](docs/a.md#calibration-paper-2-1)\n"
        "[`code` in words](docs/a.md) [web](https://example.org/x.md)\n"
        "[no file](docs/b.md) [no heading](docs/a.md#not-a-heading) [self](#page-a)\n",
        encoding="utf-8",
    )
    problems = broken_links(tmp_path)
    assert problems == [
        "README.md:3: (docs/b.md) names a file that does not exist",
        "README.md:3: (docs/a.md#not-a-heading) names a heading a.md does not have",
        "README.md:3: (#page-a) names a heading README.md does not have",
    ]


if __name__ == "__main__":
    broken = broken_links()
    print("\n".join(broken) if broken else f"all links resolve in {len(pages())} pages")
    sys.exit(1 if broken else 0)
