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

from typing import Callable, Iterable

__all__ = ["pairwise_sum", "chunk_ranges"]


def pairwise_sum(values: Iterable, add: Callable | None = None):
    """Sum of ``values`` in the fixed pairwise tree (module notes); streams, keeps O(log n) partials.

    Parameters
    ----------
    values : iterable
        Summands in block order (numbers, arrays, or tuples of them with ``add``).
    add : callable, optional
        ``add(a, b)`` (default ``a + b``); must not modify its arguments in place.

    Returns
    -------
    The sum, or None for an empty iterable.
    """
    add = add or (lambda a, b: a + b)
    stack: list[tuple[int, object]] = []  # (level, partial sum) with strictly decreasing levels
    for v in values:
        level = 0
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


def chunk_ranges(n_blocks: int, chunk_blocks: int) -> list[tuple[int, int]]:
    """Block ranges ``[lo, hi)`` of chunks of ``2^k <= chunk_blocks`` blocks (module notes)."""
    size = 1
    while 2 * size <= max(1, int(chunk_blocks)):
        size *= 2
    return [(lo, min(lo + size, n_blocks)) for lo in range(0, n_blocks, size)]
