"""Chunks kept on the workers of a Dask cluster: the solver's passes beyond one machine.

The cluster counterpart of :mod:`~mcsweep.solver.resident` (forked local workers). Each
chunk (its blocks, its measurements and a dict of its share of the star vectors of the
iteration) is one Dask future, made once per solution: scattered from the driver (what
the solver does for a problem built in the driver, in contiguous shares of the chunks
per worker), or any future of a task that built it on a worker (the primary experiment,
:mod:`mcsweep.experiments.primary.cluster`). Every pass then runs the chunk task on the
worker that holds the chunk, which reads and updates the chunk's star vectors in place:
only attitude-sized vectors and a few numbers are sent and come back
(:mod:`~mcsweep.solver.pcg`, "Where the vectors live"). The solver's passes whose outputs
are summed (:meth:`DaskChunks.reduced`) are one task per worker over the chunks it holds,
which adds their outputs where the fixed tree adds them
(:class:`~mcsweep.solver.reduction.AlignedPartials`): a few attitude-sized sums per worker
reach the driver, not one per chunk, so what travels and what the driver holds do not grow
with the number of chunks; :meth:`DaskChunks.run` (one task per chunk, every
output back) serves the others.

Results are bit-identical to in-process ones: the chunk tasks are the solver's own
functions on the same block arrays (the numba kernels sum in stored order whatever the
memory alignment, :mod:`~mcsweep.solver.kernels`), and the driver adds the chunk results
in its fixed order (:mod:`~mcsweep.solver.reduction`).

A worker lost in the middle of a solution takes the star vectors of its chunks with it:
its scattered chunks (no task to recompute them from) are scattered again from the
driver by ``rebuild`` and the solution restarts from its first pass
(:class:`~mcsweep.solver.executors.ChunksLost`); every task is deterministic, so the restarted
solution has the same bits (tested by killing a worker process of a LocalCluster
mid-solve). Only a loss restarts (a chunk's data lost, a cancelled result, a closed
connection, a time-out, a killed worker); an error of the task itself is raised at once.
Which worker holds a chunk is asked once per chunk (and again after a loss), not every
pass.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import time
import uuid

import numpy as np
from typing import Callable, Sequence

from .executors import ChunksLost, fresh_arrays
from .reduction import AlignedPartials, share_of, sum_partials

__all__ = ["DaskChunks", "is_loss", "live_workers"]


def _call(fn: Callable, ci: int, chunk: tuple, rest: tuple):
    return fn((ci, *chunk, *rest))


def _call_reduced(fn: Callable, cis: list, rests: list, specs: list, *chunks):
    """``fn`` on each of one worker's chunks ``cis`` (ascending), its outputs reduced there as
    ``specs`` say (:meth:`DaskChunks.reduced`), one chunk's outputs alive at a time."""
    folds: list = [AlignedPartials(spec[3]) if spec[0] == "tree" else None for spec in specs]
    largest: list = [None] * len(specs)
    for ci, chunk, rest in zip(cis, chunks, rests):
        out = fn((ci, *chunk, *rest))[1:]
        for k, (spec, value) in enumerate(zip(specs, out)):
            if spec[0] == "tree":
                folds[k].push(spec[1][ci], spec[2][ci], value)
            else:
                largest[k] = value if largest[k] is None else max(largest[k], value)
        del out
    return [f.partials if f is not None else m for f, m in zip(folds, largest)]


#: Exceptions by which a lost worker shows: its results cancelled, a connection closed,
#: a time-out, a task whose worker died (``distributed.scheduler.KilledWorker``, matched by
#: name so this module imports without distributed).
_LOSS = (concurrent.futures.CancelledError, OSError, TimeoutError)


def is_loss(exc: BaseException) -> bool:
    return isinstance(exc, _LOSS) or type(exc).__name__ == "KilledWorker"


#: Arrays of at least this size are scattered (once per pass and kept for the next);
#: smaller ones (a chunk's six frame sums) travel inside the task.
SCATTER_BYTES = 65536


def _scattered(obj) -> bool:
    return isinstance(obj, np.ndarray) and obj.nbytes >= SCATTER_BYTES


#: How long a pass waits for a worker when the cluster has none (all lost, nannies restarting).
WORKER_WAIT_S = 120


def live_workers(client) -> list[str]:
    """The addresses of the cluster's workers now, sorted; at least one (waits up to
    :data:`WORKER_WAIT_S` for one, then raises TimeoutError, a loss).

    Asked of the scheduler itself (``Client.nthreads``), not through
    ``Client.scheduler_info()``: distributed's client refreshes that cached identity every
    two seconds without the workers, and a refresh finishing during the call returns the
    cache with none (met in CI, distributed 2026.8: an IndexError on ``workers[0]``)."""
    workers = sorted(client.nthreads())
    if not workers:
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
        workers = sorted(client.nthreads())
    return workers


def _nbytes(obj) -> int:
    from dask.sizeof import sizeof

    return int(sizeof(obj))


class DaskChunks:
    """Chunks resident on a Dask cluster and the executor of the solver's passes over them.

    Parameters
    ----------
    client : distributed.Client
    futures : sequence of Future
        ``futures[ci]``: a future of chunk ``ci``'s tuple (the solver's: its blocks,
        measurements and a dict of its star vectors, which the tasks change in place).
    rebuild : callable, optional
        ``rebuild(ci) -> Future``: a new future of chunk ``ci`` when its data were lost with
        a worker (for scattered chunks; a chunk built by a task needs none).
    """

    #: The chunks go to the workers one by one (:class:`~mcsweep.solver.executors.ChunkHolder`).
    shares = 1

    def __init__(self, client, futures: Sequence, rebuild: Callable | None = None):
        self.client = client
        self.futures = list(futures)
        self.rebuild = rebuild
        #: Bytes sent to the workers (arguments) and received from them (results) by the
        #: passes, as counted by ``dask.sizeof`` (the arrays' sizes): measured, not estimated.
        self.bytes_sent = 0
        self.bytes_received = 0
        #: The same per task function (``fn.__name__`` -> [sent, received]): the solver's
        #: iteration passes apart from its one-off setup and residual passes.
        self.bytes_by_task: dict[str, list] = {}
        self.passes = 0
        self._pass_sent = 0
        self.repeated = 0  # losses met (each restarts the solution)
        self._previous: dict[int, tuple] = {}  # id -> (object, future) sent with the last pass
        self._homes: dict[int, list] = {}  # chunk -> the workers holding it (asked once, again after a loss)

    @classmethod
    def scatter(cls, client, chunks: Sequence[tuple]) -> "DaskChunks":
        """Chunks ``(blocks, measurements)`` held by the driver, sent once to the workers (spread
        over them), each with an empty state."""
        chunks = [(*c, {}) for c in chunks]

        def put(ci, workers=None):
            workers = workers or live_workers(client)  # the live ones (after a loss: asked again)
            # one worker per chunk, in contiguous shares: every worker gets its part of the
            # memory, and sums its chunks' outputs before they travel (:meth:`reduced`)
            # (in a list: a tuple itself would be scattered element by element)
            w = share_of(ci, len(chunks), len(workers))
            (fut,) = client.scatter([chunks[ci]], workers=[workers[w]], hash=False)
            return fut

        first = live_workers(client)  # one scheduler query for the first placement
        return cls(client, [put(ci, first) for ci in range(len(chunks))], rebuild=put)

    @contextlib.contextmanager
    def solving(self, keep: Sequence[str] = ("x",)):
        """The ``run`` of one solution's passes: the chunks' states stay on their workers, with
        everything the solution put there (``keep`` is what a caller may read afterwards)."""
        yield self.run

    def attached(self, fn: Callable, args: Sequence) -> "DaskChunks":
        """New chunks ``fn(chunk ci, args[ci])``, made on the workers holding these (pinned
        there, so nothing of the chunk moves); ``args[ci]`` is sent (scattered to that worker).
        A lost one is made again (these chunks' own rebuilt first if they were lost too)."""
        client = self.client
        sent = [0]

        def make(ci):
            home = None
            if self.futures[ci].status in ("lost", "error", "cancelled") and self.rebuild is not None:
                # Being built again: not waited for here, so every lost chunk is rebuilt at
                # once; the task goes where the scheduler puts it, next to its only large input.
                self.futures[ci] = self.rebuild(ci)
                self._homes.pop(ci, None)
            else:
                self._homes.pop(ci, None)
                home = self._home(ci)
            (arg,) = client.scatter([args[ci]], workers=home, hash=False)
            sent[0] += _nbytes(args[ci])
            # pinned: made elsewhere, the chunk (gigabytes) would be copied there
            pin = dict(workers=home, allow_other_workers=False) if home else {}
            return client.submit(fn, self.futures[ci], arg, pure=False, **pin)

        # (``make`` does not refer to the new object: a cycle would keep a finished prior's
        # chunks, and their state on the workers, until a full garbage collection)
        out = DaskChunks(client, [make(ci) for ci in range(len(self.futures))], rebuild=make)
        out.bytes_sent = sent[0]
        return out

    def _send(self, obj, ci: int | None, sent: dict):
        """A future of ``obj`` (on chunk ``ci``'s worker, or on every worker for ``None``),
        reusing the one of the previous pass if ``obj`` is the same object."""
        key = id(obj)
        if key in sent:
            return sent[key][1]
        if key in self._previous:  # the same object as last pass (held there, so the id is its own)
            sent[key] = self._previous[key]
            return sent[key][1]
        n = _nbytes(obj)
        if ci is None:
            fut = self.client.scatter(obj, broadcast=True, hash=False)
            n *= len(live_workers(self.client))
        else:
            (fut,) = self.client.scatter([obj], workers=self._home(ci), hash=False)
        self.bytes_sent += n
        self._pass_sent += n
        sent[key] = (obj, fut)
        return fut

    def _home(self, ci: int) -> list | None:
        """The one worker holding chunk ``ci`` whose copy the tasks use (one scheduler query per
        chunk and solution, not per pass; forgotten after a loss). The chunk is waited for
        first: a task of a chunk still being made, sent unpinned, may run on another worker,
        which then holds a copy of the chunk with a state of its own, so two passes could
        change two copies (met at the paper's sizes: a KeyError on a vector the previous
        pass had made). None while no worker holds it (not kept)."""
        if ci not in self._homes:
            from distributed import wait

            fut = self.futures[ci]
            wait([fut])
            holders = sorted(self.client.who_has(fut).get(fut.key) or ())
            if not holders:
                return None
            self._homes[ci] = holders[:1]
        return self._homes[ci]

    def bytes_per_call(self, *tasks: Callable) -> tuple[float, float]:
        """Bytes (sent, received) of the passes of the chunk task functions ``tasks``
        (:mod:`~mcsweep.solver.tasks`), summed."""
        got = [self.bytes_by_task.get(getattr(t, "__name__", "task"), [0, 0]) for t in tasks]
        return float(sum(g[0] for g in got)), float(sum(g[1] for g in got))

    def run(self, fn: Callable, items):
        """``fn((ci, *chunk ci, *rest))`` on chunk ``ci``'s worker for items ``(ci, *rest)``, in
        item order; only ``rest`` is sent.

        Arrays of ``rest`` of at least :data:`SCATTER_BYTES` are sent once each (an object in
        several items, the attitude vector, once to every worker) and kept for the next pass,
        which reuses them if it gets the very same objects: the caller must not modify them
        in between. Smaller ones and other objects travel with the task.

        A lost worker takes the chunk states it held: its chunks are sent again (``rebuild``)
        and :class:`~mcsweep.solver.executors.ChunksLost` is raised, so the solution restarts.
        """

        items, counts, sent = self._start_pass(items)
        try:
            args = [self._args(ci, rest, counts, sent) for ci, rest in items]
            tag = uuid.uuid4().hex[:12]
            # pinned to the chunk's worker: the task changes the chunk's state there (a copy of
            # the chunk moved to another worker would not be the one kept)
            futs = [self.client.submit(_call, fn, ci, self.futures[ci], a, workers=self._home(ci),
                                       allow_other_workers=False,
                                       key=f"{getattr(fn, '__name__', 'task')}-{ci}-{tag}", pure=False)
                    for (ci, _), a in zip(items, args)]
            out = self.client.gather(futs)
        except Exception as exc:
            self._after_failure(exc)
        self._tally(getattr(fn, "__name__", "task"), sent, out)
        return iter(out)

    def _args(self, ci: int, rest: tuple, counts: dict, sent: dict) -> tuple:
        """Chunk ``ci``'s arguments ``rest`` as its task gets them: large arrays scattered (to
        every worker if several items hold them), the rest inline."""
        return tuple(self._send(o, None if counts[id(o)] > 1 else ci, sent) if _scattered(o) else self._inline(o)
                     for o in rest)

    def _start_pass(self, items) -> tuple[list, dict, dict]:
        """A pass's items as ``(ci, rest)``, how many items hold each argument (one held by
        several is sent to every worker once), and the record of what is sent."""
        items = [(item[0], tuple(item[1:])) for item in items]
        counts: dict[int, int] = {}
        for _, rest in items:
            for obj in rest:
                counts[id(obj)] = counts.get(id(obj), 0) + 1
        self._pass_sent = 0
        return items, counts, {}

    def _after_failure(self, exc: Exception):
        """A pass failed. A worker lost mid-pass: a scatter to it or a task needing its data
        fails, before or after the scheduler marks its data lost. Give the scheduler a moment,
        send the lost chunks again and have the solution restart (raises ChunksLost). An error
        of the task itself is raised at once."""
        if not (self._lost() or is_loss(exc)):
            raise exc
        time.sleep(1.0)
        lost = self._lost()
        if lost and self.rebuild is None:
            raise exc
        for ci in lost:
            self.futures[ci] = self.rebuild(ci)
        self.repeated += 1
        self._previous = {}  # the kept vectors may have gone with the worker
        self._homes = {}
        raise ChunksLost(f"{len(lost)} chunk(s) lost with a worker: sent again") from exc

    def _tally(self, name: str, sent: dict, out: list) -> None:
        """A pass done: what it sent is kept for the next, and its bytes are counted."""
        self._previous = sent
        self.passes += 1
        received = sum(_nbytes(r) for r in out)
        self.bytes_received += received
        tally = self.bytes_by_task.setdefault(name, [0, 0])
        tally[0] += self._pass_sent
        tally[1] += received

    def reduced(self, fn: Callable, items, specs: Sequence[tuple], *, fresh: bool = True) -> list:
        """The outputs of ``fn`` over the chunks of ``items`` ``(ci, *rest)`` (as :meth:`run`),
        each reduced as ``specs[k]`` says: ``("tree", starts, levels, add)``, the sum in the fixed
        tree (:func:`~mcsweep.solver.reduction.pairwise_sum`; ``starts[ci]``, ``levels[ci]``: chunk
        ``ci``'s run), or ``("max",)``.

        One task per worker runs ``fn`` on the chunks it holds and adds their outputs there
        where the tree adds them (:class:`~mcsweep.solver.reduction.AlignedPartials`), so the
        driver receives a few sums per worker, not one per chunk, and adds them in the tree:
        the same bits as :meth:`run` and the sums taken here (tests). That task runs its
        chunks one after the other: the clusters this project starts have one thread per
        worker (a worker process per core), where nothing is lost; a worker of several threads
        would run its chunks in turn. ``fresh``: received
        arrays copied (:func:`~mcsweep.solver.executors.fresh_arrays`; not needed for sums only added
        element by element). Losses as in :meth:`run`.
        """
        items, counts, sent = self._start_pass(items)
        name = getattr(fn, "__name__", "task")
        try:
            groups: dict[str, list] = {}
            for ci, rest in sorted(items, key=lambda it: it[0]):
                home = self._home(ci)
                groups.setdefault(home[0] if home else "", []).append((ci, self._args(ci, rest, counts, sent)))
            tag = uuid.uuid4().hex[:12]
            futs = []
            for w, (worker, group) in enumerate(sorted(groups.items())):
                cis = [ci for ci, _ in group]
                futs.append(self.client.submit(
                    _call_reduced, fn, cis, [a for _, a in group], list(specs), *[self.futures[ci] for ci in cis],
                    workers=[worker] if worker else None, allow_other_workers=not worker,
                    key=f"{name}-w{w}-{tag}", pure=False))
            out = self.client.gather(futs)
        except Exception as exc:
            self._after_failure(exc)
        self._tally(name, sent, out)
        result = []
        for k, spec in enumerate(specs):
            if spec[0] == "tree":
                result.append(sum_partials((o[k] for o in out), spec[3], fresh_arrays if fresh else None))
            else:
                result.append(max(o[k] for o in out))
        return result

    def _inline(self, obj):
        """An argument sent with the task (counted)."""
        n = _nbytes(obj) if isinstance(obj, np.ndarray) else 0
        self._pass_sent += n
        self.bytes_sent += n
        return obj

    def _lost(self) -> list[int]:
        return [ci for ci, f in enumerate(self.futures) if f.status in ("lost", "error", "cancelled")]
