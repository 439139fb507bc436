"""Progress of the long stages: a live bar on a terminal, a few plain lines elsewhere.

tqdm redraws its bar with a carriage return several times a second. In a SLURM output
file, a CI log or ``> file`` every redraw becomes text, so a long sweep leaves thousands
of bar fragments. When the stream is not a terminal, :func:`progress` prints one plain
line each time another :data:`STEP_PERCENT` per cent is done (and at the end), built
with tqdm's own formatter so the line reads like the bar. A stage that is one call
(the transits of every direction) gets a line when it starts and one when it ends
(:func:`stage_line`).
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from tqdm.auto import tqdm

__all__ = ["progress", "stage_line", "LineProgress", "STEP_PERCENT"]

#: Per cent of the work between two lines of a non-terminal progress report.
STEP_PERCENT = 10
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


def progress(total: int, *, initial: int = 0, desc: str = "", unit: str = "it", enabled: bool = True,
             file: TextIO | None = None):
    """A progress reporter with ``update(n)`` and ``close()``: tqdm on a terminal, lines otherwise."""
    file = file if file is not None else sys.stderr
    if not enabled:
        return tqdm(total=total, initial=initial, disable=True)
    isatty = getattr(file, "isatty", lambda: False)()
    if isatty:
        return tqdm(total=total, initial=initial, desc=desc, unit=unit, file=file)
    return LineProgress(total, initial=initial, desc=desc, unit=unit, file=file)


def stage_line(desc: str, text: str, *, enabled: bool = True, file: TextIO | None = None) -> None:
    """One plain line ``desc: text`` on stderr, for a stage without steps to count."""
    if enabled:
        print(f"{desc}: {text}", file=file if file is not None else sys.stderr, flush=True)
