"""Which code computed a result: the package version and, from a checkout, its git commit.

Every cell file carries the :func:`code_version` that wrote it, so a run resumed after
an upgrade can tell its old cells from new ones (:class:`mcsweep.runtime.store.ResultStore`).
"""

from __future__ import annotations

import subprocess
from functools import lru_cache
from pathlib import Path

from .. import __version__

__all__ = ["git_commit", "code_version"]


def git_commit() -> str | None:
    """Commit of the checkout the package was imported from, if any (+ '-dirty')."""
    src = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "-C", str(src), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(src), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return sha + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


@lru_cache(maxsize=1)
def code_version() -> str:
    """``mcsweep <version>`` plus ``(git <commit>)`` when running from a checkout."""
    commit = git_commit()
    return f"mcsweep {__version__}" + (f" (git {commit[:12]}{'-dirty' if commit.endswith('-dirty') else ''})"
                                       if commit else "")
