"""Figures drawn in forked processes: the same files as in line, errors raised at the end."""

import errno
import multiprocessing
import os
import threading

import pytest

from mcsweep.runtime.drawing import FigureDrawer, drawing_processes

fork_only = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork here")


def _write_pid(path):
    path.write_text(str(os.getpid()))


def _fail(message):
    raise ValueError(message)


@fork_only
def test_each_figure_is_drawn_in_a_child_and_waited_for(tmp_path):
    paths = [tmp_path / f"fig{i}.txt" for i in range(5)]
    with FigureDrawer(processes=2) as drawer:
        for p in paths:
            drawer.draw(_write_pid, p)
    pids = {int(p.read_text()) for p in paths}
    assert os.getpid() not in pids and len(pids) == 5


def _disk_full(path):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))


class _Unpicklable(Exception):
    def __reduce__(self):
        raise TypeError("not this one")


def _fail_unpicklably():
    raise _Unpicklable("a lambda in the exception")


@fork_only
def test_a_figure_error_is_the_childs_exception_with_its_traceback(tmp_path):
    drawer = FigureDrawer(processes=2)
    drawer.draw(_write_pid, tmp_path / "ok.txt")
    drawer.draw(_fail, "the axes are empty")
    with pytest.raises(ValueError, match="the axes are empty") as info:
        drawer.wait()
    assert any("drawing _fail in process" in note and "Traceback" in note for note in info.value.__notes__)
    assert (tmp_path / "ok.txt").exists()
    # what the commands turn into one line and an exit status: the same as drawn in line
    drawer.draw(_disk_full, tmp_path / "fig.png")
    with pytest.raises(OSError) as info:
        drawer.wait()
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / "fig.png")
    for fn, text in ((_fail_unpicklably, "a lambda"), (_fail_to_unpickle, "two arguments"),
                     (_exit_quietly, "SystemExit")):
        drawer.draw(fn)
        with pytest.raises(RuntimeError, match=rf"drawing {fn.__name__} in process \d+ failed(.|\n)*{text}"):
            drawer.wait()


class _TwoArguments(Exception):
    def __init__(self, path, why):  # pickles, but does not unpickle: args is one string
        super().__init__(f"{path}: {why}")


def _fail_to_unpickle():
    raise _TwoArguments("fig.png", "two arguments")


def _exit_quietly():
    raise SystemExit(0)  # not the parent's exit status to take


@fork_only
def test_the_slowest_figure_holds_up_no_other(tmp_path):
    # one slot: the second figure is forked once the first has finished; with two slots, the
    # fast ones pass the slow one (the drawer waits for whichever child ends)
    with FigureDrawer(processes=2) as drawer:
        drawer.draw(_sleep_then_write, 1.0, tmp_path / "slow.txt")
        for i in range(3):
            drawer.draw(_write_pid, tmp_path / f"fast{i}.txt")
        assert all((tmp_path / f"fast{i}.txt").exists() for i in range(2))
        assert not (tmp_path / "slow.txt").exists()


def _sleep_then_write(seconds, path):
    import time

    time.sleep(seconds)
    path.write_text("done")


def test_no_processes_draws_in_line(tmp_path):
    with FigureDrawer(processes=0) as drawer:
        drawer.draw(_write_pid, tmp_path / "fig.txt")
        assert int((tmp_path / "fig.txt").read_text()) == os.getpid()  # drawn before wait
    with pytest.raises(ValueError, match="at once"):
        FigureDrawer(processes=0).draw(_fail, "at once")


def test_no_fork_while_another_thread_runs():
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        assert drawing_processes() == 0
    finally:
        stop.set()
        other.join()


@fork_only
def test_preloaded_modules_are_imported_before_the_children_fork(tmp_path, monkeypatch):
    import sys

    monkeypatch.delitem(sys.modules, "colorsys", raising=False)
    FigureDrawer(processes=0, preload=("colorsys",))
    assert "colorsys" not in sys.modules  # drawn in line: nothing to import ahead
    with FigureDrawer(processes=2, preload=("colorsys",)) as drawer:
        assert "colorsys" in sys.modules
        drawer.draw(_write_pid, tmp_path / "fig.txt")


def test_an_automatic_drawer_draws_in_line_once_a_thread_runs(tmp_path, monkeypatch):
    import mcsweep.runtime.drawing as drawing

    monkeypatch.setattr(drawing.threading, "active_count", lambda: 1)
    drawer = FigureDrawer()  # automatic: forks while this process has one thread
    monkeypatch.setattr(drawing.threading, "active_count", lambda: 2)
    with drawer:
        drawer.draw(_write_pid, tmp_path / "fig.txt")
        assert int((tmp_path / "fig.txt").read_text()) == os.getpid()
