"""The one exception type for mistakes a user can make, and how the CLIs report it.

A :class:`UserInputError` means "bad config value, bad catalogue, impossible
parameter": the command-line tools print its message as a single line on stderr and
exit with status 2, before anything is written. Ctrl-C and a full disk are neither a
user error nor a bug (one line, exit 130 or 1: :mod:`mcsweep.runtime.interruption`);
every other exception is a bug and keeps its traceback.
"""

from __future__ import annotations

import sys

__all__ = ["UserInputError", "EXIT_USER_ERROR", "report_user_error", "NotConvergedError", "EXIT_NOT_CONVERGED"]

EXIT_USER_ERROR = 2
#: A global solution that did not converge: no table is written from it.
EXIT_NOT_CONVERGED = 3


class UserInputError(ValueError):
    """A value supplied by the user is not acceptable.

    Parameters
    ----------
    message : str
        Names the offending value and says what is accepted; whitespace is folded so
        the message is one line.

    Examples
    --------
    >>> from mcsweep.errors import UserInputError
    >>> str(UserInputError('nside=3 is not accepted;   expected 2^k'))
    'nside=3 is not accepted; expected 2^k'
    """

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


def report_user_error(exc: UserInputError, prog: str = "mcsweep") -> int:
    """Print ``exc`` as one line on stderr and return the exit status to use."""
    print(f"{prog}: error: {exc}", file=sys.stderr)
    return EXIT_USER_ERROR


class NotConvergedError(RuntimeError):
    """An iterative solution stopped at its iteration limit without meeting its criterion,
    or could not start (its attitude not determined by the data under that prior).

    Not a bug and not a bad value as such (the same settings converge on other data), so
    neither a traceback nor exit status 2: one line naming the solution, its iterations
    and residual, and :data:`EXIT_NOT_CONVERGED`. Results finished before it are kept.
    """

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))
