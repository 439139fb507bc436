"""The execution backend's worker release (sweep.execution.executor)."""

from __future__ import annotations

import os
import platform
import sys

import pytest
from joblib import wrap_non_picklable_objects

from mcsweep.runtime.execution import executor
from mcsweep.command.schema import ExecutionConf


def _children() -> set[str]:
    return set(open(f"/proc/{os.getpid()}/task/{os.getpid()}/children").read().split())


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_release_workers_ends_the_loky_processes():
    # Without release joblib keeps loky's workers for reuse (they outlive the context);
    # with it, the processes the context started are gone when it ends.
    conf = ExecutionConf(backend="loky", n_jobs=2)
    with executor(conf, release_workers=True) as run:
        assert sorted(run(abs, range(-4, 4))) == sorted(abs(i) for i in range(-4, 4))
        during = _children()
    kept = {c for c in during if os.path.exists(f"/proc/{c}")}
    with executor(conf) as run:
        list(run(abs, range(8)))
    started = _children() - during
    assert started  # the next context's workers live on after it
    assert len(kept) < len(during)  # the released context's workers did not


_FAULTS = """
import resource, sys
import numpy as np
from mcsweep.runtime.execution import keep_freed_arrays
if sys.argv[1] == "keep":
    assert keep_freed_arrays()
def task():  # a sweep cell's pattern: megabyte arrays kept while larger ones come and go
    held = [np.ones(2**17 * k) for k in (1, 2)]
    b = np.ones(2**17 * 3)
    c = np.ones(2**17 * 5)
    del b
    held.append(np.ones(2**16))
    del c
    return held
task()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(50):
    task()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's allocator")
def test_a_worker_reuses_the_memory_of_freed_arrays():
    # With glibc's defaults the task's arrays (11.5 MB, 2944 pages) are mapped afresh each
    # time, the kernel faulting in and zeroing their pages; kept, they fault almost nothing.
    import subprocess

    faults = {how: int(subprocess.run([sys.executable, "-c", _FAULTS, how], capture_output=True, text=True,
                                      check=True).stdout) for how in ("default", "keep")}
    assert faults["default"] > 50 * 1000
    assert faults["keep"] < 100


# Sent to loky's workers by value: a worker cannot import this test module (the tests are
# not a package on its path in a fresh clone's virtualenv).
@wrap_non_picklable_objects
def _mark_worker(directory: str) -> None:
    open(os.path.join(directory, str(os.getpid())), "w").close()


@wrap_non_picklable_objects
def _pid(_: int) -> int:
    return os.getpid()


def test_warm_up_runs_on_the_workers_the_tasks_then_use(tmp_path):
    conf = ExecutionConf(backend="loky", n_jobs=2)
    with executor(conf, release_workers=True, warm_up=(_mark_worker, str(tmp_path))) as run:
        used = set(run(_pid, range(8)))
    warmed = {int(p.name) for p in tmp_path.iterdir()}
    assert warmed and os.getpid() not in warmed
    # The tasks ran on the executor the warm-up started (not restarted: a restart would give all
    # new workers); which worker took which warm-up is loky's choice (both may go to one).
    assert used & warmed


def test_warm_up_is_not_run_in_process_and_leaves_no_warning(tmp_path, recwarn, capfd):
    with executor(ExecutionConf(backend="loky", n_jobs=1), warm_up=(_mark_worker, str(tmp_path))) as run:
        assert list(run(_pid, range(2))) == [os.getpid()] * 2
    assert not any(tmp_path.iterdir())
    with executor(ExecutionConf(backend="loky", n_jobs=2), release_workers=True,
                  warm_up=(_mark_worker, str(tmp_path))) as run:
        assert list(run(_pid, [])) == []
    with pytest.raises(ValueError, match="a bad catalogue"):
        with executor(ExecutionConf(backend="loky", n_jobs=2), release_workers=True,
                      warm_up=(_mark_worker, str(tmp_path))):
            raise ValueError("a bad catalogue")  # before any run: the warmed workers are killed
    # kept for reuse without a run: the warm-ups are waited for, and the next context works
    with executor(ExecutionConf(backend="loky", n_jobs=2), warm_up=(_mark_worker, str(tmp_path))):
        pass
    with executor(ExecutionConf(backend="loky", n_jobs=2), release_workers=True) as run:
        assert sorted(run(abs, [-1, 2])) == [1, 2]
    assert [str(w.message) for w in recwarn] == []
    assert "Traceback" not in capfd.readouterr().err  # nor a thread's (loky's manager)
