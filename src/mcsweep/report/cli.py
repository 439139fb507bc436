"""``mcsweep-report RUN_DIR``: (re)build the report of an existing run directory.

Ctrl-C and a full disk end it with one line and exit status 130 or 1
(:mod:`mcsweep.runtime.interruption`): the run's results are only read, and each report
file is replaced whole or not at all, so running the command again finishes the report.
"""

from __future__ import annotations

import argparse
import sys

from ..errors import UserInputError, report_user_error
from ..runtime.interruption import exit_on_second_interrupt, is_disk_full, report_stop
from .build import build_report

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="mcsweep-report", description=__doc__)
    ap.add_argument("run_dir", help="directory of an mcsweep run (holds provenance.json)")
    args = ap.parse_args(argv)
    try:
        path = build_report(args.run_dir)
    except UserInputError as exc:
        return report_user_error(exc, prog="mcsweep-report")
    except (KeyboardInterrupt, OSError) as exc:
        if not isinstance(exc, KeyboardInterrupt) and not is_disk_full(exc):
            raise
        exit_on_second_interrupt()
        return report_stop("mcsweep-report", exc, f"the run's computed results in {args.run_dir} are untouched and "
                           "every file the report writes is whole (the old or the new one)",
                           "run the same command again")
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
