"""The one exception type for mistakes a user can make, and how the CLIs report it.

A :class:`UserInputError` means "bad config value, bad catalogue, impossible
parameter": the command-line tools print its message as a single line on stderr and
exit with status 2, before anything is written. Ctrl-C and a full disk are neither a
user error nor a bug (one line, exit 130 or 1: :mod:`mcsweep.sweep.interruption`);
every other exception is a bug and keeps its traceback.
"""

from __future__ import annotations

import sys

__all__ = ["UserInputError", "EXIT_USER_ERROR", "report_user_error"]

EXIT_USER_ERROR = 2


class UserInputError(ValueError):
    """A value supplied by the user is not acceptable.

    The message must name the offending value and say what is accepted, on one line.
    """

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


def report_user_error(exc: UserInputError, prog: str = "mcsweep") -> int:
    """Print ``exc`` as one line on stderr and return the exit status to use."""
    print(f"{prog}: error: {exc}", file=sys.stderr)
    return EXIT_USER_ERROR
