"""Where tasks run: joblib on local processes, or a Dask cluster through joblib.

One code path for every backend: tasks go through :class:`joblib.Parallel` inside
``joblib.parallel_config(backend=...)``; for ``dask`` a ``distributed.Client`` is
connected to the configured scheduler (or to a new local cluster of worker processes).
Tasks are seeded from their own identity, so results never depend on the backend,
the number of workers or the completion order.
"""

from __future__ import annotations

import functools
import os
import logging
import signal
import threading
import warnings
from contextlib import contextmanager
from typing import Callable, Iterable, Iterator

from joblib import Parallel, delayed, effective_n_jobs, parallel_config

from ..errors import UserInputError

__all__ = ["executor", "in_process", "dask_client", "release_free_memory", "keep_freed_arrays"]

# BLAS threads per worker: the workers already use every core (Hydra/joblib trap:
# oversubscribing 2 cores with n_jobs x BLAS threads).
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextmanager
def dask_client(conf):
    """Context of a ``distributed.Client``: of ``conf.scheduler_address``, or of a new local
    cluster of ``conf.n_jobs`` worker processes (closed on leaving). For work that keeps data
    on the workers (the primary solution, :mod:`mcsweep.solver.dask_resident`); map-like
    tasks go through :func:`executor`."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise UserInputError(
            "execution.backend='dask' needs dask.distributed; install it with pip install 'mcsweep[dask]'"
        ) from None
    if conf.scheduler_address:
        try:
            client = Client(conf.scheduler_address, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise UserInputError(f"execution.scheduler_address={conf.scheduler_address!r} is not reachable "
                                 f"({type(exc).__name__}); expected a running Dask scheduler") from None
        cluster = None
    else:
        # Ctrl-C reaches the whole process group. The workers run asyncio, whose runner turns
        # SIGINT into KeyboardInterrupt and a traceback per worker, unless SIGINT is ignored
        # when it starts: an ignored signal is inherited through fork and exec, and neither
        # Python nor asyncio.Runner installs a handler over it. So the workers are started
        # with SIGINT ignored; the parent alone acts on it (it closes the cluster).
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            # silence_logs: the workers' own warnings (a task cancelled when the cluster
            # closes on Ctrl-C) would reach the terminal; errors still do.
            # dashboard_address ':0', a free port: distributed (2026.8) reads None as its
            # default 8787 and warns on stderr when another cluster holds that port.
            cluster = LocalCluster(n_workers=conf.n_jobs, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", env={v: "1" for v in _THREAD_VARS},
                                   silence_logs=logging.ERROR)
        finally:
            signal.signal(signal.SIGINT, previous)
        client = Client(cluster)
    try:
        yield client
    finally:
        if cluster is not None:
            try:  # our own cluster's workers: their shutdown messages are not the user's business
                client.run(_quiet_worker_shutdown)
            except Exception:  # noqa: BLE001 - closing anyway (a worker may be gone, Ctrl-C)
                pass
        client.close()
        if cluster is not None:
            cluster.close()


def _quiet_worker_shutdown() -> None:
    """Run on each worker of a LocalCluster about to close. A worker still freeing gigabytes
    (the primary solution's blocks) may send its heartbeat to a scheduler that has just
    closed, and logs that as an ERROR with a traceback on the terminal (seen at the paper's
    sizes, after a complete run); its work is done by then."""
    logging.getLogger("distributed.worker").setLevel(logging.CRITICAL)
    for name in ("distributed.core", "distributed.comm"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


def ignore_sigint() -> None:
    """Run in each loky worker as it starts (its ``initializer``).

    Ctrl-C in a terminal reaches the whole process group, workers included. The parent
    alone decides what an interrupt means (it stops the workers and says what is kept);
    a worker hit by it would print its own KeyboardInterrupt traceback.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _shutdown_loky(*, kill: bool) -> None:
    from joblib.externals.loky import get_reusable_executor

    # Not reusable with these default arguments, joblib's executor is shut down by the call
    # itself (with `kill_workers`); the fresh one it returns has no process yet.
    get_reusable_executor(kill_workers=kill).shutdown(wait=True, kill_workers=kill)


def in_process(conf) -> bool:
    """Whether :func:`executor` runs its tasks one after the other in this process."""
    return conf.backend == "sequential" or (conf.n_jobs == 1 and conf.backend != "dask")


@contextmanager
def executor(conf, *, release_workers: bool = False,
             warm_up: tuple[Callable, object] | None = None) -> Iterator[Callable[[Callable, Iterable], Iterator]]:
    """Context giving ``run(fn, items)``: an iterator of ``fn(item)`` in completion order.

    ``warm_up``: ``(fn, item)``, run as the context opens as many times as there are local
    workers (loky hands one to each idle worker as it starts; that is likely, not promised), so
    the workers start (import, build what the tasks share) while this process goes on with what
    comes before the first ``run``; their results are dropped, and iterating the first ``run``
    (or leaving the context) waits for them. Only loky's local workers are warmed: in this
    process and on Dask it is not run.

    ``release_workers``: on leaving, end the local worker processes (joblib keeps loky's
    workers for reuse) so they do not hold their memory through what comes next; they are
    idle then, and are killed rather than asked to exit (an exit would first tear down each
    worker's interpreter and modules, and the parent would wait for it, 0.6 s at a sweep's end).
    Leaving on an exception (Ctrl-C, a full disk) always kills and reaps them, so no
    worker outlives the command or stays behind as a zombie.
    """
    for v in _THREAD_VARS:
        os.environ.setdefault(v, "1")

    here = in_process(conf)

    def dispatch(backend: str, n_jobs: int, fn, items):
        extra = {"initializer": ignore_sigint} if backend == "loky" else {}
        with parallel_config(backend=backend, n_jobs=n_jobs, **extra):
            # joblib starts dispatching (and loky spawns its workers) inside this call:
            # spawned with SIGINT ignored, a worker ignores it from its first instruction,
            # not only once its initializer has run (a Ctrl-C while a worker was still
            # starting under load gave it a traceback; seen in CI).
            previous = (signal.signal(signal.SIGINT, signal.SIG_IGN)
                        if backend == "loky" and threading.current_thread() is threading.main_thread() else None)
            try:
                return Parallel(return_as="generator_unordered")(delayed(fn)(i) for i in items)
            finally:
                if previous is not None:
                    signal.signal(signal.SIGINT, previous)

    warming = []

    def make_run(backend: str, n_jobs: int):
        def run(fn, items):
            items = list(items)
            # Consumed, even without tasks: closing a joblib generator early aborts its executor
            # (joblib then terminates and restarts the workers).
            while warming:
                for _ in warming.pop():
                    pass
            if here:
                yield from (fn(item) for item in items)
                return
            results = dispatch(backend, n_jobs, fn, items)
            try:
                for r in results:  # not `yield from`: closing this generator must not close that one
                    yield r
            finally:
                _close([results])  # left early (Ctrl-C, an error): joblib cancels the rest quietly
        return run

    if conf.backend == "dask":
        with dask_client(conf):
            yield make_run("dask", -1)
        return
    try:
        if warm_up is not None and not here and conf.backend == "loky":
            fn, item = warm_up
            warming.append(dispatch("loky", conf.n_jobs, fn, [item] * effective_n_jobs(conf.n_jobs)))
        yield make_run(conf.backend, conf.n_jobs)
    except BaseException:
        if conf.backend == "loky":
            _shutdown_loky(kill=True)
            _close(warming)  # their workers killed first: joblib has nothing left to abort
        raise
    else:
        if release_workers and conf.backend == "loky":
            _shutdown_loky(kill=True)
            _close(warming)
        else:  # kept for reuse: a warm-up left running would abort their executor when collected
            while warming:
                for _ in warming.pop():
                    pass


def _close(generators: list) -> None:
    """Close joblib result generators: the tasks still running are cancelled, and joblib's
    warning of results or tasks left unused (advice for a program that stops reading early on
    purpose) is not shown: a run left early was interrupted or failed, and says so itself."""
    while generators:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*tasks (have been successfully executed|which were still "
                                    "being processed)", category=UserWarning)
            generators.pop().close()


def _libc_function(name: str):
    """A function of the C library by name, or None (not glibc, or no such function)."""
    import ctypes
    import ctypes.util

    lib = ctypes.util.find_library("c")
    try:
        return getattr(ctypes.CDLL(lib), name, None) if lib else None
    except OSError:
        return None


#: glibc's ``mallopt`` parameters (malloc.h): M_TRIM_THRESHOLD and M_MMAP_THRESHOLD.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Arrays below this size come from the heap and are reused once freed (glibc's largest
#: dynamic mmap threshold on 64-bit, DEFAULT_MMAP_THRESHOLD_MAX).
_KEEP_BELOW_BYTES = 32 * 2**20
#: Free memory the heap keeps at its top before returning it.
_TRIM_ABOVE_BYTES = 64 * 2**20


@functools.cache
def keep_freed_arrays() -> bool:
    """Let this process reuse the memory of freed arrays up to 32 MB instead of returning it
    to the operating system (glibc ``mallopt``); returns whether the setting was made (False
    where glibc is not the C library).

    For a worker that makes and frees arrays of a few megabytes task after task (a sweep
    cell's noise, normal equations and scan buffers). By default glibc maps every array above
    its mmap threshold (raised only to the largest array freed so far) as fresh pages, which
    the kernel must map and zero on first touch, and unmaps it when freed; and it returns
    free heap above twice that threshold. The sweep's workers then spent a large share of
    their time in the kernel (docs/performance.md). The setting holds for the rest of the
    process (a reused worker; the command's own process when it runs the cells itself). The
    cost: freed arrays up to 32 MB stay in the heap for reuse, and free memory at its top up
    to ``_TRIM_ABOVE_BYTES``, so a process's resident set can stay higher after a task
    (a sweep worker's peak: docs/performance.md).
    """
    mallopt = _libc_function("mallopt")
    if mallopt is None:
        return False
    mmap_set = mallopt(_M_MMAP_THRESHOLD, _KEEP_BELOW_BYTES)
    trim_set = mallopt(_M_TRIM_THRESHOLD, _TRIM_ABOVE_BYTES)
    return bool(mmap_set) and bool(trim_set)


def release_free_memory() -> None:
    """Hand the heap's free pages back to the operating system (glibc ``malloc_trim``).

    Numpy arrays below glibc's mmap threshold (up to 32 MB) live in the heap; a stage that
    builds many such arrays and keeps some of them (the primary experiment's blocks of
    stars) leaves free holes between them that the allocator keeps, and trimming returns them
    (the measured saving is in docs/research_notes_moved.md). A no-op where glibc is not the
    C library.
    """
    trim = _libc_function("malloc_trim")
    if trim is not None:
        trim(0)
