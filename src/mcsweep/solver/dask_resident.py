"""Chunks kept on the workers of a Dask cluster: the solver's passes beyond one machine.

The cluster counterpart of :mod:`~mcsweep.solver.resident` (forked local workers). Each
chunk's data (its blocks and measurements, what a task item carries after its index) is
one Dask future, made once per solution: scattered from the driver, or built on a
worker by a task (then Dask recomputes it from that task if its worker is lost). Every
pass then submits one task per chunk that names the chunk's future, so the measurements
never travel again; only the small per-pass arguments (the chunk's slice of the star
vectors, the attitude vector) are sent and only the chunk results come back.

Results are bit-identical to in-process ones: the chunk tasks are the solver's own
functions on the same block arrays (the numba kernels sum in stored order whatever the
memory alignment, :mod:`~mcsweep.solver.kernels`), and the driver adds the chunk results
in its fixed order (:mod:`~mcsweep.solver.reduction`).

A worker lost in the middle of a pass: Dask reschedules the pass's tasks; a chunk built
by a task is rebuilt from that task on another worker; a scattered chunk (no task to
recompute it from) is scattered again from the driver by ``rebuild`` and the pass is
repeated. Either way the pass gives the same bits.
"""

from __future__ import annotations

import uuid
from typing import Callable, Sequence

__all__ = ["DaskChunks"]


def _call(fn: Callable, ci: int, chunk: tuple, rest: tuple):
    return fn((ci, *chunk, *rest))


def _nbytes(obj) -> int:
    from dask.sizeof import sizeof

    return int(sizeof(obj))


class DaskChunks:
    """Chunks resident on a Dask cluster and the executor of the solver's passes over them.

    Parameters
    ----------
    client : distributed.Client
    futures : sequence of Future
        ``futures[ci]``: a future of chunk ``ci``'s tuple (the solver's: its blocks and
        measurements).
    width : int
        Objects of a task item after its index that the worker holds (``len`` of the tuple).
    rebuild : callable, optional
        ``rebuild(ci) -> Future``: a new future of chunk ``ci`` when its data were lost with
        a worker (for scattered chunks; a chunk built by a task needs none).
    """

    def __init__(self, client, futures: Sequence, width: int, rebuild: Callable | None = None):
        self.client = client
        self.futures = list(futures)
        self.width = int(width)
        self.rebuild = rebuild
        #: Bytes sent to the workers (arguments) and received from them (results) by the
        #: passes, as counted by ``dask.sizeof`` (the arrays' sizes): measured, not estimated.
        self.bytes_sent = 0
        self.bytes_received = 0
        self.passes = 0

    @classmethod
    def scatter(cls, client, chunks: Sequence[tuple]) -> "DaskChunks":
        """Chunks held by the driver, sent once to the workers (spread over them)."""
        chunks = list(chunks)

        def put(ci):
            workers = sorted(client.scheduler_info()["workers"])  # the live ones (after a loss too)
            # one worker per chunk, round robin: contiguous shares are not needed (no order
            # of completion matters) and every worker gets its part of the memory
            # (in a list: a tuple itself would be scattered element by element)
            (fut,) = client.scatter([chunks[ci]], workers=[workers[ci % len(workers)]], hash=False)
            return fut

        return cls(client, [put(ci) for ci in range(len(chunks))], len(chunks[0]) if chunks else 0,
                   rebuild=put)

    def run(self, fn: Callable, items):
        """``fn(item)`` for items ``(ci, *chunk ci, *rest)``, in item order; only ``rest`` is sent."""
        items = list(items)
        rests = [tuple(item[1 + self.width:]) for item in items]
        # Objects shared by every item (the attitude vector) are sent once, to every worker;
        # the rest (each chunk's slice of the star vectors) once each.
        counts: dict[int, int] = {}
        for rest in rests:
            for obj in rest:
                counts[id(obj)] = counts.get(id(obj), 0) + 1
        shared = {}
        for rest in rests:
            for obj in rest:
                if counts[id(obj)] > 1 and id(obj) not in shared and _nbytes(obj) > 1024:
                    shared[id(obj)] = self.client.scatter(obj, broadcast=True, hash=False)
                    self.bytes_sent += _nbytes(obj) * len(self.client.scheduler_info()["workers"])
        for attempt in range(3):
            tag = uuid.uuid4().hex[:12]
            futs = []
            for item, rest in zip(items, rests):
                ci = item[0]
                args = tuple(shared.get(id(o), o) for o in rest)
                self.bytes_sent += sum(_nbytes(o) for o in rest if id(o) not in shared)
                futs.append(self.client.submit(_call, fn, ci, self.futures[ci], args,
                                               key=f"{getattr(fn, '__name__', 'task')}-{ci}-{tag}", pure=False))
            try:
                out = self.client.gather(futs)
            except Exception:
                lost = [ci for ci, f in enumerate(self.futures) if f.status in ("lost", "error", "cancelled")]
                if not lost or self.rebuild is None or attempt == 2:
                    raise
                for ci in lost:  # scattered chunks lost with a worker: send them again
                    self.futures[ci] = self.rebuild(ci)
                continue
            self.passes += 1
            self.bytes_received += sum(_nbytes(r) for r in out)
            return iter(out)
