"""Sums over blocks of stars whose rounding does not depend on how the blocks are chunked.

The attitude normal equations are sums over all stars. Floating-point addition is not
associative, so a sum taken chunk by chunk would change in the last bits with the chunk
size. Here the stars are cut into fixed *blocks* (a property of the problem, not of the
execution) and the block contributions are added in one fixed binary tree: pairwise,
left to right, an odd element carried up a level (:func:`pairwise_sum`). A chunk of
``2^k`` consecutive blocks starting at a multiple of ``2^k`` is one subtree of that tree,
so a worker can sum its own blocks and the driver can sum the chunks' results: the
result is bit-identical for every chunk size that is a power of two times the block,
every number of workers and every completion order (:func:`chunk_ranges`).
Pairwise summation also bounds the rounding error by ``O(eps log n)`` rather than
``O(eps n)`` (Higham 1993, SIAM J. Sci. Comput. 14, 783).

*Leaves.* Each block adds one attitude-sized vector per pass, dense over the mission (a
block's stars are all over the sky, seen all year). With AGIS's knots (30 s: 2.3e6
attitude unknowns at the paper's sizes; Lindegren et al. 2012, A&A 538, A78) a block of 32768 stars holds fewer
measurements (8e5) than there are attitude unknowns, and zeroing, sending and adding
those vectors costs more than the block's own work. So the attitude vectors of a pass
are summed over *leaves* of ``L`` consecutive blocks (``L`` a power of two,
:func:`leaf_blocks`, a property of the problem like the block): the blocks of a leaf
add into one vector in block order, and the leaves enter the pairwise tree as the
blocks do. Chunks are then aligned runs of leaves (:func:`chunk_ranges`'s ``leaf``), which
are aligned runs of blocks too, so per-block numbers keep their tree. ``L = 1`` (every
problem whose blocks hold more measurements than there are attitude unknowns, e.g. 3 h
knots) is the plain tree.
"""

from __future__ import annotations

import itertools
from typing import Callable, Iterable

import numpy as np

__all__ = ["pairwise_sum", "AlignedPartials", "sum_partials", "chunk_ranges", "run_level", "share_bounds", "share_of", "leaf_blocks",
           "pairwise_dot", "LEAF_RATIO", "MIN_LEAVES"]

#: A leaf holds at least this many measurements per attitude unknown (:func:`leaf_blocks`),
#: so its attitude vector (zeroed, sent, added: ~6 passes over 8 bytes per unknown) costs
#: a small part of its measurements' work (~70 bytes read each, three loops).
LEAF_RATIO = 2.0
#: ... but a problem keeps at least this many leaves (when it has that many blocks), so
#: that workers' equal shares of whole leaves stay nearly equal.
MIN_LEAVES = 8


def pairwise_dot(a, b) -> float:
    """``sum(a * b)`` by numpy's pairwise add-reduce, whose rounding, unlike BLAS ``ddot`` or
    einsum, does not depend on the operands' memory alignment."""
    return float(np.sum(np.multiply(a, b)))


def pairwise_sum(values: Iterable, add: Callable | None = None, levels: Iterable[int] | None = None):
    """Sum of ``values`` in the fixed pairwise tree (module notes); streams, keeps O(log n) partials.

    Parameters
    ----------
    values : iterable
        Summands in block order (numbers, arrays, or tuples of them with ``add``).
    add : callable, optional
        ``add(a, b)`` (default ``a + b``); may modify ``a`` in place only if the caller holds
        none of the values (every ``a`` is a value or a partial sum, used once).
    levels : iterable of int, optional
        With ``levels``, each value is the pairwise sum of ``2^level`` consecutive blocks
        starting at a multiple of ``2^level`` (an aligned run, :func:`chunk_ranges`): a
        subtree of the tree over the blocks, which enters the sum exactly where its blocks
        would have (so the result is the same bits as summing the blocks one by one).
        Default: every value is one block.

    Returns
    -------
    The sum, or None for an empty iterable.
    """
    add = add or (lambda a, b: a + b)
    stack: list[tuple[int, object]] = []  # (level, partial sum) with strictly decreasing levels
    for v, level in zip(values, itertools.repeat(0) if levels is None else levels):
        if stack and stack[-1][0] < level:
            raise ValueError(f"a run of 2^{level} blocks that does not start at a multiple of 2^{level}")
        while stack and stack[-1][0] == level:
            v = add(stack.pop()[1], v)
            level += 1
        stack.append((level, v))
    if not stack:
        return None
    total = stack.pop()[1]
    while stack:  # the carried elements, right to left
        total = add(stack.pop()[1], total)
    return total


class AlignedPartials:
    """Partial sums of the fixed tree over some of its runs, made where the runs are.

    Runs ``(start, level, value)`` (an aligned run of ``2^level`` units from ``start``, as
    :func:`pairwise_sum`'s ``levels`` describe them; a short last run enters at its level)
    are pushed in the order of ``start``, not necessarily contiguous: two are added exactly
    where the tree over all the runs adds them (contiguous, the same level, the first at a
    multiple of ``2^(level + 1)``), the others kept apart. :attr:`partials` are then aligned
    runs themselves, so :func:`pairwise_sum` of every holder's partials, in the order of their
    starts, with their levels, is the sum of all the runs, bit for bit: a worker holding
    several chunks (:mod:`~mcsweep.solver.dask_resident`) sends the driver its partials, a
    few per worker, instead of one sum per chunk.
    """

    def __init__(self, add: Callable | None = None):
        self.add = add or (lambda a, b: a + b)
        self.partials: list[tuple[int, int, object]] = []

    def push(self, start: int, level: int, value) -> None:
        stack = self.partials
        while stack:
            s0, l0, v0 = stack[-1]
            if not (l0 == level and s0 + (1 << level) == start and s0 % (1 << (level + 1)) == 0):
                break
            stack.pop()
            value, start, level = self.add(v0, value), s0, level + 1
        stack.append((start, level, value))


def sum_partials(holders: Iterable, add: Callable | None = None, each: Callable | None = None):
    """The sum of every run held as :attr:`AlignedPartials.partials` by several holders
    (``holders``: their lists of ``(start, level, value)``): :func:`pairwise_sum` of them all in
    the order of their starts, with their levels, so the fixed tree's sum bit for bit;
    ``each``: applied to each value first."""
    parts = sorted((p for held in holders for p in held), key=lambda p: p[0])
    return pairwise_sum(((p[2] if each is None else each(p[2])) for p in parts), add, [p[1] for p in parts])


def run_level(lo: int, hi: int) -> int:
    """``k`` of an aligned run ``[lo, hi)`` of ``2^k`` blocks (:func:`chunk_ranges`); for a short
    last run (fewer blocks, :func:`chunk_ranges` with leaves) the level its sum enters at."""
    return (hi - lo).bit_length() - 1


def share_bounds(n: int, shares: int) -> list[int]:
    """Bounds of ``shares`` contiguous, equal shares of ``n`` items: share ``w`` is
    ``[bounds[w], bounds[w + 1])`` (the workers' shares of the blocks or chunks)."""
    shares = max(1, int(shares))
    return [round(w * n / shares) for w in range(shares + 1)]


def share_of(i: int, n: int, shares: int) -> int:
    """The share (:func:`share_bounds`) that holds item ``i`` of ``n``."""
    return int(np.searchsorted(share_bounds(n, shares), i, side="right")) - 1


def leaf_blocks(n_blocks: int, n_measurements: int, n_att: int) -> int:
    """Blocks per leaf (module notes): the smallest power of two whose leaf holds
    :data:`LEAF_RATIO` measurements per attitude unknown (``n_att``) on average, but no larger
    than keeps :data:`MIN_LEAVES` leaves; 1 when a block alone holds enough."""
    per_block = n_measurements / max(int(n_blocks), 1)
    leaf = 1
    while leaf * per_block < LEAF_RATIO * n_att and -(-int(n_blocks) // (2 * leaf)) >= MIN_LEAVES:
        leaf *= 2
    return leaf


def chunk_ranges(n_blocks: int, chunk_blocks: int | None = 1, shares: int = 1, leaf: int = 1) -> list[tuple[int, int]]:
    """Block ranges ``[lo, hi)`` of the chunks: aligned runs (``2^k`` blocks starting at a
    multiple of ``2^k``), as long as possible up to ``chunk_blocks`` (rounded down to a power of
    two; None: no limit), covering ``shares`` contiguous, equal shares of the blocks one after
    the other (the forked workers' shares: each then sends back a few sums per pass instead
    of one per block). Every chunk is a subtree of the blocks' tree (module notes). With
    ``leaf`` blocks per leaf (a power of two) the chunks are aligned runs of whole leaves (the
    last leaf may be short: the chunk holding it ends the tree's last, carried, run)."""
    if leaf > 1:
        n_leaves = -(-int(n_blocks) // leaf)
        per = None if chunk_blocks is None else max(1, int(chunk_blocks) // leaf)
        return [(lo * leaf, min(hi * leaf, n_blocks)) for lo, hi in chunk_ranges(n_leaves, per, shares)]
    cap = None
    if chunk_blocks is not None:
        cap = 1
        while 2 * cap <= max(1, int(chunk_blocks)):
            cap *= 2
    bounds = share_bounds(n_blocks, shares)
    out = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        k = lo
        while k < hi:
            size = 1 << (hi - k).bit_length() - 1  # the largest power of two that fits
            if k:
                size = min(size, k & -k)  # and keeps the run aligned
            if cap is not None:
                size = min(size, cap)
            out.append((k, k + size))
            k += size
    return out
