"""Figures drawn in forked processes: the same files as in line, errors raised at the end."""

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


@fork_only
def test_a_figure_error_is_raised_with_the_child_traceback(tmp_path):
    drawer = FigureDrawer(processes=2)
    drawer.draw(_write_pid, tmp_path / "ok.txt")
    drawer.draw(_fail, "the axes are empty")
    with pytest.raises(RuntimeError, match=r"drawing _fail failed(.|\n)*ValueError: the axes are empty"):
        drawer.wait()
    assert (tmp_path / "ok.txt").exists()


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
