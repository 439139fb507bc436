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
"""

from __future__ import annotations

import itertools
from typing import Callable, Iterable

__all__ = ["pairwise_sum", "chunk_ranges", "run_level", "share_bounds"]


def pairwise_sum(values: Iterable, add: Callable | None = None, levels: Iterable[int] | None = None):
    """Sum of ``values`` in the fixed pairwise tree (module notes); streams, keeps O(log n) partials.

    Parameters
    ----------
    values : iterable
        Summands in block order (numbers, arrays, or tuples of them with ``add``).
    add : callable, optional
        ``add(a, b)`` (default ``a + b``); must not modify its arguments in place.
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


def run_level(lo: int, hi: int) -> int:
    """``k`` of an aligned run ``[lo, hi)`` of ``2^k`` blocks (:func:`chunk_ranges`)."""
    return (hi - lo).bit_length() - 1


def share_bounds(n: int, shares: int) -> list[int]:
    """Bounds of ``shares`` contiguous, equal shares of ``n`` items: share ``w`` is
    ``[bounds[w], bounds[w + 1])`` (the workers' shares of the blocks or chunks)."""
    shares = max(1, int(shares))
    return [round(w * n / shares) for w in range(shares + 1)]


def chunk_ranges(n_blocks: int, chunk_blocks: int | None = 1, shares: int = 1) -> list[tuple[int, int]]:
    """Block ranges ``[lo, hi)`` of the chunks: aligned runs (``2^k`` blocks starting at a
    multiple of ``2^k``), as long as possible up to ``chunk_blocks`` (rounded down to a power of
    two; None: no limit), covering ``shares`` contiguous, equal shares of the blocks one after
    the other (the forked workers' shares: each then sends back a few sums per pass instead
    of one per block). Every chunk is a subtree of the blocks' tree (module notes)."""
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
