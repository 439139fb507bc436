"""Check that docs/table3.md's lines all landed on the pages of docs/notes/table3/, once each.

    python docs/scripts/check_table3_split.py [ORIGINAL_REV [PAGES_REV]]

ORIGINAL_REV is a commit whose docs/table3.md is the notebook before the split (default: the
parent of the commit that split it); PAGES_REV a commit whose docs/notes/table3/*.md to read
(default: the working tree). Headings compare without their leading '#', so a heading moved to
another level still counts. Prints every line of the original not found on the pages as often
as it occurs there, every line found more often, and the lines the pages add (titles, dates,
the index's table); exits 1 if a line of the original is missing or duplicated.
"""

import subprocess
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGES = "docs/notes/table3"


def git(*args):
    return subprocess.run(["git", "-C", str(ROOT), *args], check=True, capture_output=True,
                          text=True).stdout


def norm(line):
    line = line.rstrip()
    return line.lstrip("#").lstrip() if line.startswith("#") else line


def main():
    original_rev = sys.argv[1] if len(sys.argv) > 1 else None
    pages_rev = sys.argv[2] if len(sys.argv) > 2 else None
    if original_rev is None:
        split = git("log", "--format=%H", "--diff-filter=A", "--", f"{PAGES}/index.md").split()[-1]
        original_rev = f"{split}^"
    original = git("show", f"{original_rev}:docs/table3.md").splitlines()
    if pages_rev is None:
        texts = {p.name: p.read_text() for p in sorted((ROOT / PAGES).glob("*.md"))}
    else:
        names = git("ls-tree", "--name-only", f"{pages_rev}:{PAGES}").split()
        texts = {n: git("show", f"{pages_rev}:{PAGES}/{n}") for n in names if n.endswith(".md")}
    want = Counter(norm(s) for s in original if s.strip())
    have = Counter(norm(s) for t in texts.values() for s in t.splitlines() if s.strip())
    missing = want - have
    extra = have - want
    doubled = {s: have[s] - want[s] for s in want if have[s] > want[s]}
    print(f"original: {len(original)} lines ({sum(want.values())} non-blank) at {original_rev}; "
          f"pages: {len(texts)} files, {sum(have.values())} non-blank lines")
    for s, n in missing.items():
        print(f"MISSING x{n}: {s}")
    for s, n in doubled.items():
        print(f"DUPLICATED x{n}: {s}")
    added = [s for s in extra if s not in want]
    print(f"{len(added)} lines added by the pages (titles, dates, the index's table), "
          f"{len(missing)} missing, {len(doubled)} duplicated")
    return 1 if missing or doubled else 0


if __name__ == "__main__":
    sys.exit(main())
