"""A report's figures drawn side by side in forked processes while the report is built.

A sweep's report is mostly matplotlib drawing its figures one after the other (2.6 of the
default report's 3.1 s, docs/performance.md), and each figure is a file that nothing else in
the report reads. :class:`FigureDrawer` runs each ``draw`` call in a child forked from this
process (it starts with matplotlib and the figure's data already in memory: nothing is
imported or pickled) and :meth:`~FigureDrawer.wait` collects them: a figure's error is
raised there as the exception the child met (a full disk is the same ``OSError`` as in line,
a Ctrl-C the same ``KeyboardInterrupt``), with the child's traceback as a note.

Drawing stays in this process where forking is not safe or not possible: on platforms
without ``fork`` (macOS and Windows start processes afresh), while other threads run (a
child forked then could inherit a lock another thread holds), or with one core.
"""

from __future__ import annotations

import gc
import importlib
import multiprocessing
import os
import pickle
import select
import sys
import threading
import traceback
from collections.abc import Callable

__all__ = ["FigureDrawer", "drawing_processes"]

#: At most this many drawing processes at once: a report has about ten figures, each child
#: holds its figure's memory.
MAX_DRAWING_PROCESSES = 4


def drawing_processes() -> int:
    """How many processes :class:`FigureDrawer` would draw in at once now: 0 where it draws in
    line (module notes), else twice the cores this process may use (a figure is forked while
    a slower one still draws; the cores share them), at most :data:`MAX_DRAWING_PROCESSES`."""
    if "fork" not in multiprocessing.get_all_start_methods() or threading.active_count() > 1:
        return 0
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return min(2 * cores, MAX_DRAWING_PROCESSES) if cores > 1 else 0


class FigureDrawer:
    """Runs figure-drawing calls in forked processes (module notes); use as a context.

    ``processes``: how many at once (None: :func:`drawing_processes`, and in line whenever a
    thread has started since; 0 draws in line).
    ``preload``: modules to import here before the first child is forked, so that no child
    imports them again (matplotlib's pyplot: half a second each).
    """

    def __init__(self, processes: int | None = None, *, preload: tuple[str, ...] = ()):
        self._processes = drawing_processes() if processes is None else int(processes)
        self._watch_threads = processes is None  # an explicit number is the caller's judgement
        if self._processes > 0:
            for name in preload:
                importlib.import_module(name)
        self._running: dict[int, tuple[int, str]] = {}  # pid -> (read end of its pipe, figure)
        self._failures: list[str] = []

    def draw(self, fn: Callable, *args, **kwargs) -> None:
        """Call ``fn(*args, **kwargs)``, which writes a figure file, now or in a child
        process; its return value is dropped."""
        if self._processes <= 0 or (self._watch_threads and threading.active_count() > 1):  # one started since
            fn(*args, **kwargs)
            return
        while len(self._running) >= self._processes:
            self._reap(block=True)
        for stream in (sys.stdout, sys.stderr):  # or the child would write it out again
            stream.flush()
        read, write = os.pipe()
        try:
            pid = os.fork()
        except BaseException:
            os.close(read)
            os.close(write)
            raise
        if pid == 0:  # the child: draw, report an error through the pipe, never return
            status = 1
            try:
                gc.disable()  # no finalizer of the parent's garbage runs here
                os.close(read)
                fn(*args, **kwargs)
                status = 0
            except BaseException as exc:
                message = _failure_message(exc)
                while message:
                    message = message[os.write(write, message):]
            finally:
                for stream in (sys.stdout, sys.stderr):
                    try:
                        stream.flush()
                    except BaseException:
                        pass
                os._exit(status)
        os.close(write)
        self._running[pid] = (read, getattr(fn, "__name__", repr(fn)))

    def _reap(self, *, block: bool) -> None:
        """Collect the children that have finished; with ``block``, wait until one has."""
        reads = {read: pid for pid, (read, _) in self._running.items()}
        # A child's pipe reaches its end when the child exits: read to it first (a long
        # traceback fills the pipe), then reap; a child leaves the list once reaped.
        ready, _, _ = select.select(list(reads), [], [], None if block else 0)
        for read in ready:
            pid = reads[read]
            with os.fdopen(os.dup(read), "rb") as pipe:
                message = pipe.read()
            _, status = os.waitpid(pid, 0)
            _, name = self._running.pop(pid)
            os.close(read)
            code = os.waitstatus_to_exitcode(status)
            if code != 0:
                self._failures.append(_failure(message, f"drawing {name} in process {pid}", code))

    def wait(self) -> None:
        """Wait for every figure; raises the first failed figure's exception (module notes)."""
        while self._running:
            self._reap(block=True)
        failures, self._failures = self._failures, []
        if failures:
            first = failures[0]
            for other in failures[1:]:
                first.add_note(f"also failed: {type(other).__name__}: {other}")
            raise first

    def __enter__(self) -> "FigureDrawer":
        return self

    def __exit__(self, *exc) -> None:
        if exc[0] is None:
            self.wait()
            return
        # The report failed (or was interrupted): no child outlives it, none is left a zombie.
        for pid, (read, _) in list(self._running.items()):
            for step in (lambda: os.close(read), lambda: os.waitpid(pid, 0)):
                try:
                    step()
                except OSError:  # closed or reaped already (an interrupt mid-way)
                    pass
            self._running.pop(pid, None)


def _failure_message(exc: BaseException) -> bytes:
    """What a failed child sends its parent: its traceback's text and, pickled apart, the
    exception (left out if it does not pickle; a SystemExit is not the parent's to raise)."""
    text = traceback.format_exc()
    try:
        pickled = b"" if isinstance(exc, SystemExit) else pickle.dumps(exc)
    except Exception:
        pickled = b""
    return pickle.dumps((text, pickled))


def _failure(message: bytes, what: str, code: int) -> BaseException:
    """The exception a failed child reported, with its traceback as a note; a RuntimeError
    with the traceback where there is no exception to raise (killed by a signal, or an
    exception that does not pickle or unpickle)."""
    text, exc = "", None
    try:
        text, pickled = pickle.loads(message)
        exc = pickle.loads(pickled) if pickled else None
    except Exception:
        pass
    if not isinstance(exc, BaseException):
        return RuntimeError(f"{what} failed (exit status {code})" + (f":\n{text}" if text else ""))
    exc.add_note(f"{what}:\n{text}")
    return exc
