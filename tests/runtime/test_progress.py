"""Progress in logs that are not a terminal: whole lines every few per cent, no carriage returns."""

import io
import subprocess
import sys

from mcsweep.runtime.progress import STEP_PERCENT, LineProgress, progress, stage_line


class _Tty(io.StringIO):
    def isatty(self):
        return True


def test_non_terminal_gets_one_line_per_step_and_no_carriage_return():
    out = io.StringIO()
    bar = progress(480, desc="cells", unit="cells", file=out)
    assert isinstance(bar, LineProgress)
    for _ in range(480):
        bar.update(1)
    bar.close()
    text = out.getvalue()
    lines = text.splitlines()
    assert "\r" not in text
    assert len(lines) == 100 // STEP_PERCENT
    assert lines[0].startswith("cells: 48/480 cells ( 10 %)")
    assert lines[-1].startswith("cells: 480/480 cells (100 %)")


def test_resumed_run_reports_from_where_it_restarts_and_ends_with_the_total():
    out = io.StringIO()
    bar = progress(48, initial=45, desc="cells", unit="cells", file=out)
    for _ in range(3):
        bar.update(1)
    bar.close()
    lines = out.getvalue().splitlines()
    assert lines == [ln for ln in lines if "\r" not in ln] and lines[-1].startswith("cells: 48/48 cells (100 %)")
    assert len(lines) == 1


def test_partial_last_step_is_reported_at_close():
    out = io.StringIO()
    bar = progress(1000, desc="chunks", unit="chunks", file=out)
    for _ in range(105):  # 10.5 %: the 10 % line, nothing more until close
        bar.update(1)
    assert len(out.getvalue().splitlines()) == 1
    bar.close()
    bar.close()
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and lines[-1].startswith("chunks: 105/1000 chunks ( 10 %)")


def test_terminal_keeps_the_live_bar_and_disabled_prints_nothing():
    tty = _Tty()
    bar = progress(10, desc="cells", file=tty)
    bar.update(10)
    bar.close()
    assert "\r" in tty.getvalue()
    quiet = io.StringIO()
    bar = progress(10, desc="cells", enabled=False, file=quiet)
    bar.update(10)
    bar.close()
    assert quiet.getvalue() == ""


def test_stage_line_is_one_plain_line_and_silent_when_disabled():
    out = io.StringIO()
    stage_line("transits", "scanning law over 3 directions", file=out)
    stage_line("transits", "hidden", enabled=False, file=out)
    assert out.getvalue() == "transits: scanning law over 3 directions\n"


def test_a_long_solution_gets_a_line_a_minute_saying_where_it_stands():
    # SolveLines (the primary experiment's PCG log): one line per `every` seconds of wall
    # time, none for a solution shorter than that, none when progress is off.
    from types import SimpleNamespace

    from mcsweep.runtime.progress import SolveLines

    now = [0.0]
    out = io.StringIO()
    lines = SolveLines("mcsweep: primary: prior F90", lambda r: f"estimated error {r.error_estimate:g}",
                       "error 0.01", every=60.0, file=out, clock=lambda: now[0])
    for k in range(1, 301):  # 300 iterations of 0.5 s: 150 s, so lines at 60 and 120 s
        now[0] = 0.5 * k
        lines(SimpleNamespace(iteration=k, seconds=0.5 * k, error_estimate=1000.0 / k))
    assert out.getvalue().splitlines() == [
        "mcsweep: primary: prior F90: iteration 120 (0.50 s each), estimated error 8.33333; stops at error 0.01",
        "mcsweep: primary: prior F90: iteration 240 (0.50 s each), estimated error 4.16667; stops at error 0.01"]
    quiet = io.StringIO()
    off = SolveLines("x", str, "y", every=0.0, enabled=False, file=quiet, clock=lambda: now[0])
    off(SimpleNamespace(iteration=1, seconds=1.0))
    assert quiet.getvalue() == ""


_BARS_THEN_THREADS = """
import io, threading
from mcsweep.runtime.progress import progress
class Tty(io.StringIO):
    def isatty(self):
        return True
for enabled, file in ((False, io.StringIO()), (True, Tty())):
    bar = progress(10, desc="cells", enabled=enabled, file=file)
    bar.update(10)
    bar.close()
print(threading.active_count())
"""


def test_no_thread_outlives_a_bar():
    # A thread left running (tqdm's monitor) would make the report draw its figures in line
    # (mcsweep.runtime.drawing forks only a single-threaded process); a fresh interpreter, so
    # no other test's bar is counted.
    out = subprocess.run([sys.executable, "-c", _BARS_THEN_THREADS], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "1", out
