"""Executors of the solver's chunk tasks, their results in chunk order, and lost chunks.

A pass of the solver runs one chunk task (:mod:`~mcsweep.solver.tasks`) on every chunk
through ``run(fn, items)``, an executor that holds each chunk (its blocks, measurements and
the state with its share of the star vectors) where its task runs: in this process
(:func:`in_process`, :class:`HeldChunks`), in a forked worker (:func:`~mcsweep.solver.resident.forked_chunks`) or
on a Dask worker (:class:`~mcsweep.solver.dask_resident.DaskChunks`). Items are
``(ci, *rest)``; the executor calls the task with ``(ci, *chunk, *rest)``. Results may come
in any order; :func:`ordered` puts them back in chunk order as fresh arrays, so the driver's
sums in the fixed tree of :mod:`~mcsweep.solver.reduction` are the same bits whatever ran
them. A worker lost with its chunks' states raises :class:`ChunksLost`, and the solution
restarts from its first pass (every task is deterministic, so with the same bits) up to
:data:`MAX_RESTARTS` times (:func:`retried`). :class:`ChunkPasses` runs a pass and sums the chunks' outputs in
the fixed trees, here or where the chunks are.
"""

from __future__ import annotations

import contextlib
from typing import Callable, ContextManager, Iterable, Iterator, Protocol, Sequence, runtime_checkable

import numpy as np

from .reduction import pairwise_sum, run_level
from .resident import forked_chunks

__all__ = ["ChunksLost", "MAX_RESTARTS", "ChunkHolder", "ChunkPasses", "HeldChunks", "in_process", "fresh_arrays",
           "ordered", "chunk_values", "retried", "state_vectors"]

#: Restarts of a solution after lost chunk states before the loss is raised.
MAX_RESTARTS = 3


class ChunksLost(RuntimeError):
    """Raised by a resident executor when a worker and the chunk states it held were lost;
    its chunks' data are back on the cluster and the solution restarts (deterministic, so
    with the same bits)."""


def retried(action: Callable, retry_if: Callable, between: Callable = lambda: None):
    """``action()``, repeated up to :data:`MAX_RESTARTS` times when it raises an exception
    ``retry_if`` accepts (a loss), ``between()`` first; any other raised at once."""
    for attempt in range(MAX_RESTARTS + 1):
        try:
            return action()
        except Exception as exc:  # noqa: BLE001 - only what retry_if accepts is repeated
            if attempt == MAX_RESTARTS or not retry_if(exc):
                raise
            between()


@runtime_checkable
class ChunkHolder(Protocol):
    """What holds a problem's chunks ``(blocks, measurements, state)`` where their tasks run,
    the one interface the solver (:func:`~mcsweep.solver.solve.solve_global`'s
    ``resident_chunks``) and the primary experiment (:mod:`mcsweep.experiments.primary.
    prior_solution`) use: :class:`HeldChunks` (this process, or forked workers for one
    solution) and :class:`~mcsweep.solver.dask_resident.DaskChunks` (a cluster's workers).
    Another backend (another process pool, a GPU) is one module implementing it; the tasks
    reach their compiled kernels through :mod:`~mcsweep.solver.kernel_backend`.

    Attributes
    ----------
    shares : int
        The chunks are this many equal shares of the blocks
        (:meth:`~mcsweep.solver.problem.GlobalProblem.chunks`), one per worker that keeps a
        share for a whole solution; 1 when chunks go to workers one by one.
    reduced : callable or None
        ``reduced(fn, items, specs, fresh=...)``: a pass whose outputs are summed where the
        chunks are, in the fixed trees (:class:`ChunkPasses`); None: the driver sums them.
    """

    shares: int
    reduced: Callable | None

    def run(self, fn: Callable, items) -> Iterator:
        """``fn((ci, *chunk ci, *rest))`` for items ``(ci, *rest)``, where chunk ``ci`` is, its
        results in any order; raises :class:`ChunksLost` when chunk states were lost."""

    def attached(self, fn: Callable, args: Sequence) -> "ChunkHolder":
        """New chunks ``fn(chunk ci, args[ci])``, made where these are."""

    def solving(self, keep: Sequence[str] = ("x",)) -> ContextManager[Callable]:
        """The ``run`` of one solution's passes; afterwards each state keeps the vectors
        ``keep`` of the solution besides what it held."""


def in_process(chunks, fn: Callable, items: Iterable) -> Iterator:
    """The in-process executor over chunks ``(blocks, measurements, state)`` it holds
    (``chunks[ci]``); items are ``(ci, *rest)`` as for the resident executors."""
    return (fn((item[0], *chunks[item[0]], *item[1:])) for item in items)


def state_vectors(item):
    """The vectors ``names`` of a chunk's state (:meth:`HeldChunks.solving`)."""
    ci, _, _, st, names = item
    return ci, {k: st[k] for k in names}


class HeldChunks:
    """Chunks ``(blocks, measurements, state)`` held in this process, a :class:`ChunkHolder`
    (as :class:`~mcsweep.solver.dask_resident.DaskChunks` on a cluster), so one sequence of
    chunk tasks serves chunks here and there.

    A solution's passes (:meth:`solving`) run here or, with ``workers >= 2`` (and ``fork``),
    on forked workers (:func:`~mcsweep.solver.resident.forked_chunks`; ``owners[ci]``: chunk
    ``ci``'s worker) that keep their share of the chunks and states for that solution; the
    state vectors asked for come back when it ends, and the tasks after it run here.
    ``shares``: the chunks fall in that many equal shares of the blocks (one per worker,
    :meth:`~mcsweep.solver.problem.GlobalProblem.chunks`)."""

    #: The driver sums every pass's outputs (:class:`ChunkHolder`).
    reduced = None

    def __init__(self, chunks: Sequence[tuple], workers: int = 1, owners: Sequence[int] | None = None):
        self.chunks = [tuple(c) for c in chunks]
        self.workers, self.owners = max(1, int(workers)), owners

    @property
    def shares(self) -> int:
        return self.workers

    def run(self, fn: Callable, items) -> Iterator:
        """``fn((ci, *chunk ci, *rest))`` here for items ``(ci, *rest)``."""
        return in_process(self.chunks, fn, items)

    def attached(self, fn: Callable, args: Sequence) -> "HeldChunks":
        """New chunks ``fn(chunk ci, args[ci])``, made here."""
        return HeldChunks([fn(c, a) for c, a in zip(self.chunks, args)], self.workers, self.owners)

    @contextlib.contextmanager
    def solving(self, keep: Sequence[str] = ("x",)):
        """The executor ``run(fn, items)`` of one solution's passes (module notes): here, or on
        forked workers. Afterwards each state holds what it held before plus the vectors
        ``keep`` (the solution's others are let go)."""
        before = [set(c[2]) for c in self.chunks]
        with forked_chunks(self.chunks, self.workers, owners=self.owners) as pool:
            yield self.run if pool is None else pool
            if pool is not None and keep:
                for ci, got in pool(state_vectors, [(ci, tuple(keep)) for ci in range(len(self.chunks))]):
                    self.chunks[ci][2].update(got)
        for (_, _, st), names in zip(self.chunks, before):
            for k in set(st) - names - set(keep):
                del st[k]


def fresh_arrays(obj):
    """Arrays copied into new allocations: results unpickled from a worker may sit at any
    memory alignment, and numpy's SIMD reductions (dot, einsum) may round differently
    with alignment; fresh copies behave as arrays computed in this process."""
    if isinstance(obj, np.ndarray):
        return np.array(obj, copy=True)
    if isinstance(obj, (list, tuple)):
        return type(obj)(fresh_arrays(o) for o in obj)
    if isinstance(obj, dict):
        return {k: fresh_arrays(v) for k, v in obj.items()}
    return obj


def ordered(run, fn, items) -> list:
    """Results of ``run(fn, items)`` (any completion order) in the order of the items ``(ci, ...)``, as fresh arrays
    (:func:`fresh_arrays`; an executor whose ``run`` has ``fresh_results`` gives them so already:
    the forked workers', :mod:`~mcsweep.solver.resident`, where a second copy of every
    attitude vector cost a third of the driver's time at AGIS's knots)."""
    is_fresh = getattr(run, "fresh_results", False)
    out = dict((r[0], r[1:] if is_fresh else fresh_arrays(r[1:])) for r in run(fn, items))
    return [out[item[0]] for item in items]  # items (ci, ...): any chunks, not only 0 .. n - 1


def chunk_values(run, fn, items) -> list:
    """The one value of each chunk task ``fn`` returning ``(ci, value)``, run by ``run`` (any
    completion order), in chunk order and as fresh arrays (:func:`fresh_arrays`)."""
    return [r[0] for r in ordered(run, fn, items)]


class ChunkPasses:
    """The passes of one solution over its chunks: each chunk task run on all chunks by
    ``run(fn, items)`` and its outputs summed in the fixed trees of
    :mod:`~mcsweep.solver.reduction`, per-block numbers in the blocks' tree and attitude
    vectors in the leaves' tree, so the sums do not depend on the chunking or on where the
    chunks ran. ``reduced(fn, items, specs, fresh=)``: an executor that sums the chunks'
    outputs where they are (:meth:`~mcsweep.solver.dask_resident.DaskChunks.reduced`: a few
    sums per worker reach the driver, not one per chunk); None: the chunks' outputs are
    summed here. ``chunks``: each chunk's blocks, aligned runs of whole leaves
    (``problem.chunks``)."""

    def __init__(self, problem, chunks, run, reduced=None):
        self.run, self.reduced = run, reduced
        self.n_ch = range(len(chunks))
        self.levels = [run_level(0, len(bl)) for bl in chunks]
        # each chunk's leaves (local block ranges): its blocks' attitude vectors are summed per leaf
        bs, leaf = (problem.blocks[0].n if problem.blocks else 1), problem.leaf
        if any((bl[0].first // bs) % leaf for bl in chunks):
            raise ValueError(f"chunks must start at a leaf of {leaf} blocks (problem.chunks)")
        self.leaves = [[(j, min(j + leaf, len(bl))) for j in range(0, len(bl), leaf)] for bl in chunks]
        self.leaf_levels = [run_level(0, len(lv)) for lv in self.leaves]
        # the chunks' runs in the two trees (first block or leaf, level), for sums taken where the chunks are
        first_block = [bl[0].first // bs for bl in chunks]
        self.block_tree = first_block, self.levels
        self.leaf_tree = [f // leaf for f in first_block], self.leaf_levels
        self._sums = {"blocks": self.total, "leaves": self.total_att}

    def total(self, values, add=None):
        """Sum over the chunks (each an aligned run of blocks) in the blocks' fixed tree."""
        return pairwise_sum(values, add, self.levels)

    def total_att(self, values, add=None):
        """Sum of the chunks' attitude vectors (each an aligned run of leaves) in the leaves' tree."""
        return pairwise_sum(values, add, self.leaf_levels)

    def ordered(self, fn, items) -> list:
        """Every chunk's outputs of ``fn``, in the order of the items (:func:`ordered`)."""
        return ordered(self.run, fn, items)

    def summed(self, fn, items, trees, *, fresh=True):
        """The outputs of the chunk tasks ``fn`` over all chunks, summed: ``trees[k]`` is
        ``("blocks" | "leaves", add)`` for a sum in that tree, or ``("max", None)``. Where the
        chunks are (``reduced``) or here from each chunk's outputs: the same bits. ``fresh``
        False (one output, added element by element): summed as received, each chunk's
        dropped once added (the setup's are large)."""
        if self.reduced is not None:
            specs = [("max",) if t == "max" else ("tree", *(self.block_tree if t == "blocks" else self.leaf_tree), add)
                     for t, add in trees]
            return self.reduced(fn, items, specs, fresh=fresh)
        if not fresh:
            ((t, add),) = trees
            got = {r[0]: r[1] for r in self.run(fn, items)}
            return [self._sums[t]((got.pop(i) for i in self.n_ch), add)]
        out = ordered(self.run, fn, items)
        return [max(o[k] for o in out) if t == "max" else self._sums[t]((o[k] for o in out), add)
                for k, (t, add) in enumerate(trees)]
