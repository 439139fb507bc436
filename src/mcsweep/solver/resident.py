"""Chunk workers that keep their blocks: the solver's passes on the cores of one machine.

Every PCG iteration makes two passes over all measurements (:mod:`~mcsweep.solver.pcg`).
A map-like executor (joblib's loky processes) re-sends each chunk's measurements with
every call, which costs more than the pass itself (measured 5.8x the in-process wall
time; :func:`~mcsweep.solver.solve.solve_global`). Here the workers are *forked* once per
solution, after the problem is built: each inherits the blocks and the measurements
copy-on-write (nothing is copied or sent; the solver only reads them) and owns a fixed,
contiguous share of the chunks, and with them the star vectors of the iteration (kept
in each chunk's state, :mod:`~mcsweep.solver.pcg`). A pass then sends each worker only
attitude-sized vectors and a few numbers, and receives the same.

Results are bit-identical to in-process ones: a child computes on the very arrays (same
memory addresses, so the same alignment) the parent would, and the solver adds the
chunk results in its fixed order (:mod:`~mcsweep.solver.reduction`).

Messages carry their arrays out of band (pickle protocol 5: each array's buffer is handled
as it lies, not copied into one pickled string first), and each task's result goes back as
soon as it is made, the parent reading whichever worker is ready. A worker then holds one
result at a time, once: at the paper's sizes with AGIS's knots a chunk's setup result was an
attitude band of 12 x 2.3e6 doubles, and two of them plus the pickled copy of both were the
run's peak memory (measured, docs/notes/table3/solver_cost.md; the band now comes in slabs).

Large buffers (at least ``ARENA_MIN_BYTES``) do not go through the pipe but through two
*arenas* per worker, anonymous shared mappings made before the fork: the sender copies the
buffer into its arena, the pipe carries where it lies, and the receiver copies it out at once
into an array of its own. With AGIS's 30 s knots every pass returns attitude vectors of
2.3e6 doubles (18.5 MB), which an arena passes in a fraction of the pipe's time and of the
parent's CPU (measured: docs/solver_design.md, "Forked workers' arenas").
An arena is reused message after message (the parent sends a worker's next message only once
it has read every result of the last, and each side copies out what it receives at once);
what does not fit in it goes through the pipe. The bytes are the same either way.

Only where the ``fork`` start method exists (Linux, macOS); elsewhere :func:`forked_chunks`
yields ``None`` and the caller runs in-process. On a Dask cluster
:mod:`~mcsweep.solver.dask_resident` keeps the chunks on the workers in the same way.
"""

from __future__ import annotations

import contextlib
import io
import mmap
import multiprocessing as mp
import pickle
import signal
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
from typing import Callable, Iterator, Sequence

import numpy as np

from .reduction import share_bounds

__all__ = ["forked_chunks", "fork_available", "ARENA_BYTES", "ARENA_MIN_BYTES"]

#: Size of each of a worker's two arenas (module notes): two chunks' attitude vectors at AGIS's
#: knots and the paper's sizes (2 x 18.5 MB) or two setup slabs (2 x 32 MiB) fit. Only the pages
#: written hold memory.
ARENA_BYTES = 80 << 20
#: Buffers at least this large go through the arenas; smaller ones stay in the pipe message.
ARENA_MIN_BYTES = 1 << 20
#: Offsets in an arena are multiples of this (a cache line).
_ALIGN = 64


def fork_available() -> bool:
    return "fork" in mp.get_all_start_methods()


class Arena:
    """One direction's shared buffer between the parent and a worker (module notes): a shared
    anonymous mapping made before the fork, written from ``cursor`` on, rewound per message."""

    def __init__(self, size: int):
        self.size = int(size)
        self.map = mmap.mmap(-1, self.size) if self.size else None
        self.cursor = 0

    def rewind(self) -> None:
        self.cursor = 0

    def put(self, raw: memoryview) -> int:
        """Copy ``raw`` (bytes) in at the cursor and return its offset, or -1 if it does not fit."""
        n = raw.nbytes
        if self.map is None or n < ARENA_MIN_BYTES or self.cursor + n > self.size:
            return -1
        at = self.cursor
        self.map[at:at + n] = raw
        self.cursor = -(-(at + n) // _ALIGN) * _ALIGN
        return at

    def take(self, at: int, n: int) -> np.ndarray:
        """A new array holding the ``n`` bytes at ``at`` (copied out: the arena is reused)."""
        out = np.empty(n, dtype=np.uint8)
        out[:] = np.frombuffer(self.map, dtype=np.uint8, count=n, offset=at)
        return out

    def close(self) -> None:
        if self.map is not None:
            self.map.close()
            self.map = None


def _send(conn: Connection, obj, arena: Arena | None = None) -> None:
    """``obj`` pickled with its buffers out of band: the places of the buffers (an offset in
    ``arena``, or -1: in the pipe) and their sizes, the pickle, then each pipe buffer written
    from where it lies (module notes)."""
    buffers, head = [], io.BytesIO()
    ForkingPickler(head, pickle.HIGHEST_PROTOCOL, True, buffers.append).dump(obj)  # (file, protocol, fix_imports, buffer_callback)
    raws = [b.raw() for b in buffers]
    places = [(arena.put(r) if arena is not None else -1, r.nbytes) for r in raws]
    conn.send_bytes(np.array(places, dtype=np.int64).reshape(-1, 2).tobytes())
    conn.send_bytes(head.getbuffer())
    for (at, _), r in zip(places, raws):
        if at < 0:
            conn.send_bytes(r)


def _recv(conn: Connection, arena: Arena | None = None):
    """What :func:`_send` sent, its arrays on new allocations of this process (copied out of
    ``arena`` or of the pipe's bytes): they behave as arrays computed here (the solver's
    ``executors.fresh_arrays`` rule), whatever the sender's memory alignment."""
    places = np.frombuffer(conn.recv_bytes(), dtype=np.int64).reshape(-1, 2)
    head = conn.recv_bytes()
    return pickle.loads(head, buffers=[_from_pipe(conn, int(n)) if at < 0 else arena.take(int(at), int(n))
                                       for at, n in places])


def _from_pipe(conn: Connection, n: int) -> np.ndarray:
    """The next ``n``-byte message, read straight into a new array (one copy, not two)."""
    out = np.empty(n, dtype=np.uint8)
    conn.recv_bytes_into(out)
    return out


def _serve(conn: Connection, chunks: dict, down: Arena, up: Arena) -> None:
    """Worker loop: run ``fn((ci, *chunks[ci], *rest))`` for every task of a message, each
    result sent when made; after an error, the error and nothing more for that message.
    ``down``, ``up``: the arenas of the messages and of the results (module notes)."""
    # Ctrl-C reaches the terminal's whole process group; only the parent acts on it (it
    # ends the pool). SIGINT stayed blocked since the fork, so none can slip in before this.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    while True:
        msg = _recv(conn, down)
        if msg is None:
            return
        fn, tasks = msg
        del msg
        up.rewind()  # the parent has copied out every result of the last message
        for ci, rest in tasks:
            try:
                out = fn((ci, *chunks[ci], *rest))
            except BaseException as exc:  # noqa: BLE001 - handed to the parent, which re-raises
                _send(conn, ("error", exc), up)
                break
            _send(conn, ("ok", out), up)
            del out


class _Pool:
    def __init__(self, chunks: Sequence, n_workers: int, owners: Sequence[int] | None = None):
        ctx = mp.get_context("fork")
        n = len(chunks)
        if owners is None:  # contiguous, equal shares of the chunks
            bounds = share_bounds(n, n_workers)
            owners = [w for w in range(n_workers) for _ in range(bounds[w], bounds[w + 1])]
        self.owner = {}
        self.conns, self.procs, self.downs, self.ups = [], [], [], []
        # Blocked across the forks (children inherit the mask; _serve then ignores it);
        # an interrupt meanwhile reaches this process when the mask is restored.
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            for w in range(n_workers):
                own = {ci: chunks[ci] for ci in range(n) if owners[ci] == w}
                for ci in own:
                    self.owner[ci] = w
                parent, child = ctx.Pipe()
                down, up = Arena(ARENA_BYTES), Arena(ARENA_BYTES)  # mapped before the fork: shared
                p = ctx.Process(target=_serve, args=(child, own, down, up), daemon=True)
                p.start()
                child.close()
                self.conns.append(parent)
                self.procs.append(p)
                self.downs.append(down)
                self.ups.append(up)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)

    def run(self, fn: Callable, items) -> Iterator:
        """``fn((ci, *chunks[ci], *rest))`` for items ``(ci, *rest)``: only ``ci, rest`` are sent
        (the worker holds ``chunks[ci]``, and keeps what ``fn`` changes in it). The results'
        arrays are new allocations of this process (:func:`_recv`: ``fresh_results``)."""
        per = [[] for _ in self.conns]
        for item in items:
            per[self.owner[item[0]]].append((item[0], tuple(item[1:])))
        busy = [w for w, tasks in enumerate(per) if tasks]
        for w in busy:  # every worker reads its whole message before it computes: no deadlock
            self.downs[w].rewind()  # it has copied out the last message (its results are all in)
            _send(self.conns[w], (fn, per[w]), self.downs[w])
        # every reply is read, from whichever worker is ready (none waits on a full pipe while
        # another is read), so none is left behind for the next pass
        got, left, error = {w: [] for w in busy}, {w: len(per[w]) for w in busy}, None
        worker = {self.conns[w]: w for w in busy}
        while left:
            for conn in wait([self.conns[w] for w in left]):
                w = worker[conn]
                status, out = _recv(conn, self.ups[w])
                if status == "error":
                    error = error or out
                    del left[w]  # it stops at its error
                    continue
                got[w].append(out)
                left[w] -= 1
                if not left[w]:
                    del left[w]
        if error is not None:
            raise error
        return (r for w in busy for r in got[w])

    #: What :func:`_recv` gives: the solver need not copy the results again (``executors.ordered``).
    run.fresh_results = True

    def close(self, *, kill: bool = False) -> None:
        """End the workers: after their current task, or at once with ``kill`` (the parent
        was interrupted or failed, their results are not wanted)."""
        for c in self.conns if not kill else ():
            with contextlib.suppress(OSError):
                _send(c, None)
        for p in self.procs:
            if kill:
                p.terminate()
            p.join(timeout=10)
            if p.is_alive():
                p.terminate()
        for c in self.conns:
            c.close()
        for a in (*self.downs, *self.ups):
            a.close()


@contextlib.contextmanager
def forked_chunks(chunks: Sequence[tuple], n_workers: int, owners: Sequence[int] | None = None):
    """Context of ``n_workers`` forked workers owning ``chunks`` (module notes): yields
    their ``run(fn, items)`` executor, or ``None`` with fewer than 2 workers or chunks, or
    without ``fork``. ``chunks[ci]`` is a tuple of what the worker keeps (the solver's:
    the chunk's blocks, measurements and a dict of its star vectors, which the tasks
    change in place); an item ``(ci, *rest)`` runs ``fn((ci, *chunks[ci], *rest))`` there.
    ``owners[ci]``: the worker of chunk ``ci`` (default: contiguous, equal shares of the
    chunks; ignored if it names more workers than there are chunks)."""
    if n_workers < 2 or len(chunks) < 2 or not fork_available():
        yield None
        return
    n_workers = min(int(n_workers), len(chunks))
    if owners is not None and (max(owners) >= n_workers or len(set(owners)) < n_workers):
        owners = None
    pool = _Pool(chunks, n_workers, owners)
    try:
        yield pool.run
    except BaseException:
        pool.close(kill=True)
        raise
    pool.close()
