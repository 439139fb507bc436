"""Chunk workers that keep their blocks: the solver's passes on the cores of one machine.

Every PCG iteration makes two passes over all measurements (:mod:`~mcsweep.solver.cg`).
A map-like executor (joblib's loky processes) re-sends each chunk's measurements with
every call, which costs more than the pass itself (measured 5.8x the in-process wall
time; :func:`~mcsweep.solver.cg.solve_global`). Here the workers are *forked* once per
solution, after the problem is built: each inherits the blocks and the measurements
copy-on-write (nothing is copied or sent; the solver only reads them) and owns a fixed,
contiguous share of the chunks, and with them the star vectors of the iteration (kept
in each chunk's state, :mod:`~mcsweep.solver.cg`). A pass then sends each worker only
attitude-sized vectors and a few numbers, and receives the same.

Results are bit-identical to in-process ones: a child computes on the very arrays (same
memory addresses, so the same alignment) the parent would, and the solver adds the
chunk results in its fixed order (:mod:`~mcsweep.solver.reduction`).

Messages carry their arrays out of band (pickle protocol 5: each array's buffer is written
to the pipe as it lies, not copied into one pickled string first), and each task's result
goes back as soon as it is made, the parent reading whichever worker is ready. A worker then
holds one result at a time, once: at the paper's sizes with AGIS's knots a chunk's setup
result was an attitude band of 12 x 2.3e6 doubles, and two of them plus the pickled copy of
both were the run's peak memory (measured, docs/table3.md; the band now comes in slabs).

Only where the ``fork`` start method exists (Linux, macOS); elsewhere :func:`forked_chunks`
yields ``None`` and the caller runs in-process. On a Dask cluster
:mod:`~mcsweep.solver.dask_resident` keeps the chunks on the workers in the same way.
"""

from __future__ import annotations

import contextlib
import io
import multiprocessing as mp
import pickle
import signal
import struct
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
from typing import Callable, Iterator, Sequence

from .reduction import share_bounds

__all__ = ["forked_chunks", "fork_available"]


def fork_available() -> bool:
    return "fork" in mp.get_all_start_methods()


def _send(conn: Connection, obj) -> None:
    """``obj`` pickled with its buffers out of band: the count, the pickle, then each buffer
    written from where it lies (module notes)."""
    buffers, head = [], io.BytesIO()
    ForkingPickler(head, pickle.HIGHEST_PROTOCOL, True, buffers.append).dump(obj)  # (file, protocol, fix_imports, buffer_callback)
    conn.send_bytes(struct.pack("<q", len(buffers)))
    conn.send_bytes(head.getbuffer())
    for b in buffers:
        conn.send_bytes(b.raw())


def _recv(conn: Connection):
    """What :func:`_send` sent (its arrays read-only views of the received buffers)."""
    n = struct.unpack("<q", conn.recv_bytes())[0]
    head = conn.recv_bytes()
    return pickle.loads(head, buffers=[conn.recv_bytes() for _ in range(n)])


def _serve(conn: Connection, chunks: dict) -> None:
    """Worker loop: run ``fn((ci, *chunks[ci], *rest))`` for every task of a message, each
    result sent when made; after an error, the error and nothing more for that message."""
    # Ctrl-C reaches the terminal's whole process group; only the parent acts on it (it
    # ends the pool). SIGINT stayed blocked since the fork, so none can slip in before this.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    while True:
        msg = _recv(conn)
        if msg is None:
            return
        fn, tasks = msg
        del msg
        for ci, rest in tasks:
            try:
                out = fn((ci, *chunks[ci], *rest))
            except BaseException as exc:  # noqa: BLE001 - handed to the parent, which re-raises
                _send(conn, ("error", exc))
                break
            _send(conn, ("ok", out))
            del out


class _Pool:
    def __init__(self, chunks: Sequence, n_workers: int, owners: Sequence[int] | None = None):
        ctx = mp.get_context("fork")
        n = len(chunks)
        if owners is None:  # contiguous, equal shares of the chunks
            bounds = share_bounds(n, n_workers)
            owners = [w for w in range(n_workers) for _ in range(bounds[w], bounds[w + 1])]
        self.owner = {}
        self.conns, self.procs = [], []
        # Blocked across the forks (children inherit the mask; _serve then ignores it);
        # an interrupt meanwhile reaches this process when the mask is restored.
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            for w in range(n_workers):
                own = {ci: chunks[ci] for ci in range(n) if owners[ci] == w}
                for ci in own:
                    self.owner[ci] = w
                parent, child = ctx.Pipe()
                p = ctx.Process(target=_serve, args=(child, own), daemon=True)
                p.start()
                child.close()
                self.conns.append(parent)
                self.procs.append(p)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)

    def run(self, fn: Callable, items) -> Iterator:
        """``fn((ci, *chunks[ci], *rest))`` for items ``(ci, *rest)``: only ``ci, rest`` are sent
        (the worker holds ``chunks[ci]``, and keeps what ``fn`` changes in it)."""
        per = [[] for _ in self.conns]
        for item in items:
            per[self.owner[item[0]]].append((item[0], tuple(item[1:])))
        busy = [w for w, tasks in enumerate(per) if tasks]
        for w in busy:  # every worker reads its whole message before it computes: no deadlock
            _send(self.conns[w], (fn, per[w]))
        # every reply is read, from whichever worker is ready (none waits on a full pipe while
        # another is read), so none is left behind for the next pass
        got, left, error = {w: [] for w in busy}, {w: len(per[w]) for w in busy}, None
        worker = {self.conns[w]: w for w in busy}
        while left:
            for conn in wait([self.conns[w] for w in left]):
                w = worker[conn]
                status, out = _recv(conn)
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
