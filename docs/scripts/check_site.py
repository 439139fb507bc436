"""Checks of the documentation that ``sphinx-build -W`` lets through; exit status 1 on any.

1. Raw reST roles in the built HTML (``:func:`` ... shown as text: MyST pages need
   ``{func}`` or plain code spans).
2. Markdown table rows whose number of cells differs from their table's header (an
   unescaped ``|`` inside a cell splits it).
3. A page that would reach the network: a script or stylesheet loaded from another host
   (the site must work offline; MathJax is bundled, ``sphinx-mathjax-offline``).
4. A code line wider than the text column on a user's page (the guide, the start page, the
   method, the experiment pages and the tutorial): over :data:`CODE_COLUMN` characters it is
   clipped in the theme's column, and the reader of a command cannot see its end.

Run after the build: ``python docs/scripts/check_site.py BUILD_DIR`` (from the repository's
root; the Markdown sources are read from ``docs/``).
"""

from __future__ import annotations

import html
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]
RAW_ROLE = re.compile(r":(?:func|class|mod|meth|attr|data|doc|ref|math|obj|exc):(?:<code|`)")
REMOTE = re.compile(r"<(?:script|link)\b[^>]*(?:src|href)=\"(?:https?:)?//[^\"]+\"", re.IGNORECASE)
CODE_SPAN = re.compile(r"`[^`]*`")
PRE = re.compile(r"<pre[^>]*>(.*?)</pre>", re.DOTALL)
TAG = re.compile(r"<[^>]+>")
#: Characters of monospace that fit the theme's 630 px text column at its code font size.
CODE_COLUMN = 75
#: The pages a user reads to run and use mcsweep (research notes may hold wide tables of logs).
USER_PAGES = ("index.html", "method.html", "guide/", "experiments/", "auto_examples/", "api/")


def _cells(row: str) -> int:
    row = CODE_SPAN.sub("", row.strip()).replace(r"\|", "")
    return row.strip("|").count("|") + 1


def table_problems(path: Path) -> list[str]:
    out, header, fence = [], None, False
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if line.lstrip().startswith(("```", "~~~")):
            fence = not fence
        if fence or not line.lstrip().startswith("|"):
            header = None
            continue
        cells = _cells(line)
        if header is None:
            header = cells
        elif cells != header:
            out.append(f"{path.relative_to(DOCS.parent)}:{n}: {cells} cells, the table's header has {header}")
    return out


def wide_code(name, text: str) -> list[str]:
    """The code lines of a built page wider than :data:`CODE_COLUMN` characters."""
    out = []
    for block in PRE.findall(text):
        for line in html.unescape(TAG.sub("", block)).splitlines():
            if len(line.rstrip()) > CODE_COLUMN:
                out.append(f"{name}: code line of {len(line.rstrip())} characters (> {CODE_COLUMN}): {line.strip()[:60]}")
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1 or not Path(argv[0]).is_dir():
        print("usage: python docs/scripts/check_site.py BUILD_DIR", file=sys.stderr)
        return 2
    build = Path(argv[0])
    problems = []
    for page in sorted(build.rglob("*.html")):
        text = page.read_text(errors="replace")
        for m in RAW_ROLE.finditer(text):
            problems.append(f"{page.relative_to(build)}: raw role {m.group(0)[:12]!r}")
        for m in REMOTE.finditer(text):
            problems.append(f"{page.relative_to(build)}: loads from the network: {m.group(0)[:80]}")
        if str(page.relative_to(build)).startswith(USER_PAGES):
            problems.extend(wide_code(page.relative_to(build), text))
    for source in sorted(DOCS.rglob("*.md")):
        if "_build" in source.parts or "auto_examples" in source.parts:
            continue
        problems.extend(table_problems(source))
    for p in problems:
        print(p)
    print(f"check_site: {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
