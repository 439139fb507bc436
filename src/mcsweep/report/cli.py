"""``mcsweep-report RUN_DIR``: (re)build the report of an existing run directory."""

from __future__ import annotations

import argparse
import sys

from ..errors import UserInputError, report_user_error
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
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
