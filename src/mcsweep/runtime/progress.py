"""Progress of the long stages: a live bar on a terminal, a few plain lines elsewhere.

tqdm redraws its bar with a carriage return several times a second. In a SLURM output
file, a CI log or ``> file`` every redraw becomes text, so a long sweep leaves thousands
of bar fragments. When the stream is not a terminal, :func:`progress` prints one plain
line each time another :data:`STEP_PERCENT` per cent is done (and at the end), built
with tqdm's own formatter so the line reads like the bar. A stage that is one call
(the transits of every direction) gets a line when it starts and one when it ends
(:func:`stage_line`). A global solution, whose iterations are not known in advance, gets a
line every :data:`SOLVE_LINE_SECONDS` seconds saying where it stands (:class:`SolveLines`).
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from tqdm.auto import tqdm

__all__ = ["progress", "stage_line", "LineProgress", "SolveLines", "STEP_PERCENT", "SOLVE_LINE_SECONDS"]

#: Per cent of the work between two lines of a non-terminal progress report.
STEP_PERCENT = 10
#: Seconds between two lines of a running global solution (:class:`SolveLines`): at the paper's
#: sizes with AGIS's knots one prior takes 10-60 min (docs/notes/table3/candidates_paper_sizes.md).
SOLVE_LINE_SECONDS = 60.0
_FORMAT = "{desc}: {n_fmt}/{total_fmt} {unit} ({percentage:3.0f} %) [{elapsed} elapsed, {remaining} left]"


class LineProgress:
    """tqdm's ``update``/``close`` interface writing a whole line every ``step`` per cent."""

    def __init__(self, total: int, *, initial: int = 0, desc: str = "", unit: str = "it",
                 step: float = STEP_PERCENT, file: TextIO | None = None):
        self.total, self.n, self.desc, self.unit, self.step = total, initial, desc, unit, step
        self.file = file if file is not None else sys.stderr
        self.t0 = time.monotonic()
        self.initial = initial
        self._last = self._bucket()  # what was already done when the run (re)started is not news
        self._printed = initial

    def _bucket(self) -> int:
        return int(100.0 * self.n / self.total // self.step) if self.total else 0

    def _line(self) -> None:
        elapsed = time.monotonic() - self.t0
        # Rate and time left from this session's work only (a resumed run starts at `initial`).
        done = self.n - self.initial
        left = (self.total - self.n) * elapsed / done if done > 0 else None
        text = tqdm.format_meter(self.n, self.total, elapsed, prefix=self.desc, unit=self.unit,
                                 bar_format=_FORMAT.replace("{remaining}", tqdm.format_interval(left)
                                                            if left is not None else "?"))
        print(text, file=self.file, flush=True)
        self._printed = self.n

    def update(self, n: int = 1) -> None:
        self.n += n
        b = self._bucket()
        if b > self._last:
            self._last = b
            self._line()

    def close(self) -> None:
        if self.n != self._printed:
            self._line()  # the last, partial step (once: close may be called again)


class _Bar(tqdm):
    """tqdm's bar without its monitor thread, which outlives the bar (tqdm 4.70) and would make
    the report draw its figures in line (mcsweep.runtime.drawing forks only a single-threaded
    process); the monitor only adjusts ``miniters`` of bars that stall."""

    monitor_interval = 0


class _Silent:
    """The reporter of a disabled progress: counts, says nothing."""

    def __init__(self, total: int, initial: int = 0):
        self.total, self.n = total, initial

    def update(self, n: int = 1) -> None:
        self.n += n

    def close(self) -> None:
        pass


def progress(total: int, *, initial: int = 0, desc: str = "", unit: str = "it", enabled: bool = True,
             file: TextIO | None = None):
    """A progress reporter with ``update(n)`` and ``close()``: tqdm on a terminal, lines otherwise."""
    file = file if file is not None else sys.stderr
    if not enabled:
        return _Silent(total, initial)  # no tqdm at all: even a disabled one starts the monitor
    isatty = getattr(file, "isatty", lambda: False)()
    if isatty:
        return _Bar(total=total, initial=initial, desc=desc, unit=unit, file=file)
    return LineProgress(total, initial=initial, desc=desc, unit=unit, file=file)


def stage_line(desc: str, text: str, *, enabled: bool = True, file: TextIO | None = None) -> None:
    """One plain line ``desc: text`` on stderr, for a stage without steps to count."""
    if enabled:
        print(f"{desc}: {text}", file=file if file is not None else sys.stderr, flush=True)


class SolveLines:
    """A PCG solution's ``log`` callback (:func:`mcsweep.solver.solve_global`) that prints, at most
    every ``every`` seconds, one line ``desc: iteration K (S s each), STATE; stops at GOAL``.

    ``every`` defaults to :data:`SOLVE_LINE_SECONDS` (read when the solution starts).
    ``state(record)`` says where the solution stands in its stopping rule's terms (the estimated
    error, or the last update) and ``goal`` what it stops at, so a user can judge from the line
    whether a long solution is getting there. No line for a solution shorter than ``every``; a
    solution made of several PCG runs (calibration unknowns) restarts its iteration count, and the
    line says so through ``K``.
    """

    def __init__(self, desc: str, state, goal: str, *, every: float | None = None,
                 enabled: bool = True, file: TextIO | None = None, clock=time.monotonic):
        self.desc, self.state, self.goal, self.enabled = desc, state, goal, enabled
        self.every = float(SOLVE_LINE_SECONDS if every is None else every)
        self.file = file if file is not None else sys.stderr
        self.clock = clock
        self._last = clock()

    def __call__(self, record) -> None:
        now = self.clock()
        if not self.enabled or now - self._last < self.every:
            return
        self._last = now
        each = record.seconds / record.iteration if record.iteration > 0 else float("nan")
        print(f"{self.desc}: iteration {record.iteration} ({each:.2f} s each), {self.state(record)}; "
              f"stops at {self.goal}", file=self.file, flush=True)
