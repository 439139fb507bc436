"""Executors of the solver's chunk tasks, their results in chunk order, and lost chunks.

A pass of the solver runs one chunk task (:mod:`~mcsweep.solver.tasks`) on every chunk
through ``run(fn, items)``, an executor that holds each chunk (its blocks, measurements and
the state with its share of the star vectors) where its task runs: in this process
(:func:`in_process`), in a forked worker (:func:`~mcsweep.solver.resident.forked_chunks`) or
on a Dask worker (:class:`~mcsweep.solver.dask_resident.DaskChunks`). Items are
``(ci, *rest)``; the executor calls the task with ``(ci, *chunk, *rest)``. Results may come
in any order; :func:`ordered` puts them back in chunk order as fresh arrays, so the driver's
sums in the fixed tree of :mod:`~mcsweep.solver.reduction` are the same bits whatever ran
them. A worker lost with its chunks' states raises :class:`ChunksLost`, and the solution
restarts from its first pass (every task is deterministic, so with the same bits) up to
:data:`MAX_RESTARTS` times. :class:`ChunkPasses` runs a pass and sums the chunks' outputs in
the fixed trees, here or where the chunks are.
"""

from __future__ import annotations

from typing import Callable, Iterable, Iterator

import numpy as np

from .reduction import pairwise_sum, run_level

__all__ = ["ChunksLost", "MAX_RESTARTS", "ChunkPasses", "in_process", "fresh_arrays", "ordered", "chunk_values"]

#: Restarts of a solution after lost chunk states before the loss is raised.
MAX_RESTARTS = 3


class ChunksLost(RuntimeError):
    """Raised by a resident executor when a worker and the chunk states it held were lost;
    its chunks' data are back on the cluster and the solution restarts (deterministic, so
    with the same bits)."""


def in_process(chunks: dict, fn: Callable, items: Iterable) -> Iterator:
    """The in-process executor over chunks ``(blocks, measurements, state)`` it holds; items
    are ``(ci, *rest)`` as for the resident executors."""
    return (fn((item[0], *chunks[item[0]], *item[1:])) for item in items)


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
