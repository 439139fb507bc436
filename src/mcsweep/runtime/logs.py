"""Where a job's log records go: everything to the run's log file, little to the terminal.

Hydra gives the root logger a console handler and a file handler (``<job>.log`` in the
run directory), both at INFO. Third-party libraries log their own INFO lines through
it: a Dask cluster alone prints some 45 lines (scheduler, nanny and worker start and
stop) between the progress bar and the result line. The terminal keeps warnings and
errors from everyone and every line of mcsweep's own loggers; the log file keeps all.
"""

from __future__ import annotations

import logging

__all__ = ["OwnOrWarning", "quiet_third_party_console"]

_OWN = "mcsweep"


class OwnOrWarning(logging.Filter):
    """Pass records of mcsweep's loggers at any level, and others from WARNING up."""

    def filter(self, record: logging.LogRecord) -> bool:
        own = record.name == _OWN or record.name.startswith(_OWN + ".")
        return own or record.levelno >= logging.WARNING


def quiet_third_party_console(logger: logging.Logger | None = None) -> None:
    """Add :class:`OwnOrWarning` to the console handlers of ``logger`` (default: root).

    File handlers are left alone, so the run's log keeps the full record. Idempotent.
    """
    logger = logger if logger is not None else logging.getLogger()
    for handler in logger.handlers:
        console = isinstance(handler, logging.StreamHandler) and not isinstance(handler, logging.FileHandler)
        if console and not any(isinstance(f, OwnOrWarning) for f in handler.filters):
            handler.addFilter(OwnOrWarning())
