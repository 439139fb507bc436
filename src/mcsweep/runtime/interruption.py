"""How a command stopped by Ctrl-C or a full disk tells its user what is kept and what to do.

Neither is a bug nor a user error, so neither deserves a traceback on the terminal (the
``mcsweep`` command still writes it to the run's log file): the command ends with one
line on stderr and an exit status that says why:

- :data:`EXIT_INTERRUPTED` = 130 (128 + SIGINT, what a shell reports for a command ended
  by Ctrl-C, so scripts and SLURM see an interruption);
- :data:`EXIT_DISK_FULL` = 1 (no space left, or the disk quota exceeded: the environment
  failed, not the config, so not :data:`~mcsweep.errors.EXIT_USER_ERROR`).

Nothing half-written survives either: every file goes through
:func:`~mcsweep.runtime.store.atomic_write_via`, which removes its temporary on any error,
and a rerun reads only files that pass the store's checks. What is kept is read back
from the run directory (:meth:`~mcsweep.runtime.store.ResultStore.finished`), not from
counters of the stopped process, which a worker's last write may have outrun.
"""

from __future__ import annotations

import errno
import os
import signal
import sys

from .store import remove_temporaries

__all__ = ["EXIT_INTERRUPTED", "EXIT_DISK_FULL", "RESUME", "is_disk_full", "report_stop",
           "exit_on_second_interrupt", "remove_unfinished_writes"]

EXIT_INTERRUPTED = 128 + signal.SIGINT
EXIT_DISK_FULL = 1
RESUME = "run the same command to resume"
_NO_SPACE = (errno.ENOSPC, errno.EDQUOT)


def is_disk_full(exc: BaseException) -> bool:
    """True for an OSError of a full disk or quota, also when another error wraps it."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, OSError) and exc.errno in _NO_SPACE:
            return True
        exc = exc.__cause__ or exc.__context__
    return False


def _disk_full_error(exc: BaseException) -> OSError:
    while not (isinstance(exc, OSError) and exc.errno in _NO_SPACE):
        exc = exc.__cause__ or exc.__context__
    return exc


def report_stop(prog: str, exc: BaseException, kept: str, next_step: str = RESUME) -> int:
    """Print the one line for an interrupt or a full disk; returns the exit status.

    ``kept``: what the user still has ("171 of 672 cells kept in RUN_DIR");
    ``next_step``: how to go on once the cause is gone.
    """
    if is_disk_full(exc):
        err = _disk_full_error(exc)
        where = f" writing {err.filename}" if err.filename else ""
        reason = "disk quota exceeded" if err.errno == errno.EDQUOT else "no space left on device"
        print(f"{prog}: error: {reason}{where}; {kept}; free space, then {next_step}", file=sys.stderr, flush=True)
        return EXIT_DISK_FULL
    print(f"{prog}: interrupted: {kept}; {next_step}", file=sys.stderr, flush=True)
    return EXIT_INTERRUPTED


def exit_on_second_interrupt() -> None:
    """From now on Ctrl-C ends the process at once, still without a traceback.

    Called when the first one is being handled: the user pressing again while workers
    are shut down and the kept results are counted wants out, not a second traceback.
    """
    signal.signal(signal.SIGINT, lambda *_: os._exit(EXIT_INTERRUPTED))


def remove_unfinished_writes(run_dir) -> int:
    """Delete the temporaries of writes that never finished anywhere under ``run_dir``.

    A worker process killed by its parent on Ctrl-C (:func:`mcsweep.runtime.execution.executor`)
    may die between creating a temporary and moving it into place, where its own clean-up
    never runs. Called once the workers are reaped, so no live write owns one.
    """
    return remove_temporaries(run_dir, recursive=True)
