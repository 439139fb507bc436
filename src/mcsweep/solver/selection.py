"""Exact order statistics of float64 values spread over chunks, without gathering them.

The frame penalty (:func:`~mcsweep.solver.frame.penalty_weights`) is set by the medians of two
per-star weights. On a cluster the stars stay with their chunks (nothing per star reaches the driver), so the medians
are found by radix selection on an order-preserving 64-bit key of each value: four rounds,
each one task per chunk returning how many of its values fall under each 16-bit digit
below the prefix fixed so far (:func:`digit_counts`, sparse), after which the driver knows
the next 16 bits of the wanted value's key (:func:`select`). The result is the value itself,
bit for bit, so :func:`median` equals :func:`numpy.median` of all the values (tests), and
what travels is a few digit histograms per chunk, never the values.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

__all__ = ["DIGIT_BITS", "float_keys", "digit_counts", "select", "median", "quantile_ranks",
           "quantile_from_neighbours"]

#: Bits of the key fixed per round (four rounds for a 64-bit key).
DIGIT_BITS = 16
_ROUNDS = 64 // DIGIT_BITS
_MASK = np.uint64((1 << DIGIT_BITS) - 1)


def float_keys(values, dtype=np.float64) -> np.ndarray:
    """Unsigned keys in the order of ``values`` as ``dtype`` (float64: 64-bit keys; float32:
    32-bit): the IEEE-754 bits with every bit of a negative number flipped, only the sign bit
    of a positive one."""
    bits = np.dtype(dtype).itemsize * 8
    utype = np.uint64 if bits == 64 else np.uint32
    u = np.ascontiguousarray(values, dtype=dtype).view(utype)
    top = utype(bits - 1)
    return np.where(u >> top == 1, ~u, u | (utype(1) << top))


def _value(key: int) -> float:
    k = np.uint64(key)
    u = k & ~np.uint64(1 << 63) if k >> np.uint64(63) == 1 else ~k
    return float(np.array([u], dtype=np.uint64).view(np.float64)[0])


def digit_counts(values, queries: Sequence[tuple[int, int]]) -> list[tuple[np.ndarray, np.ndarray]]:
    """The chunk's side of a round: per query ``(prefix, round)``, the values whose key's top
    ``16 round`` bits equal ``prefix``, counted by their next 16 bits: (digits, counts)."""
    keys = float_keys(values)
    out = []
    for prefix, rnd in queries:
        shift = np.uint64(64 - DIGIT_BITS * (rnd + 1))
        k = keys if rnd == 0 else keys[(keys >> np.uint64(64 - DIGIT_BITS * rnd)) == np.uint64(prefix)]
        digits, counts = np.unique((k >> shift) & _MASK, return_counts=True)
        out.append((digits, counts))
    return out


def select(counts_of: Callable[[list], list], ranks: Sequence[int]) -> list[float]:
    """The values of ``ranks`` (0-based, ascending order of all the chunks' values).

    ``counts_of(queries)`` runs :func:`digit_counts` with ``queries`` on every chunk's values
    and returns the chunks' results in any order (the counts are added)."""
    state = [(0, int(r)) for r in ranks]  # (prefix, rank within the prefix's values)
    for rnd in range(_ROUNDS):
        got = counts_of([(prefix, rnd) for prefix, _ in state])
        nxt = []
        for i, (prefix, rank) in enumerate(state):
            total: dict[int, int] = {}
            for chunk in got:
                for d, c in zip(chunk[i][0].tolist(), chunk[i][1].tolist()):
                    total[d] = total.get(d, 0) + c
            below = 0
            for d in sorted(total):
                if rank < below + total[d]:
                    nxt.append(((prefix << DIGIT_BITS) | d, rank - below))
                    break
                below += total[d]
            else:
                raise ValueError(f"rank {ranks[i]} is beyond the {below} values")
        state = nxt
    return [_value(prefix) for prefix, _ in state]


def median(counts_of: Callable[[list], list], n: int) -> float:
    """:func:`numpy.median` of ``n`` values spread over chunks (:func:`select`): the middle
    value, or the mean of the two middle ones as numpy takes it."""
    if n <= 0:
        return float("nan")
    if n % 2:
        return select(counts_of, [n // 2])[0]
    a, b = select(counts_of, [n // 2 - 1, n // 2])
    return float(np.mean(np.array([a, b])))


def quantile_ranks(n: int, quantiles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two neighbouring ranks (0-based) and the weight of :func:`numpy.quantile`'s 'linear'
    method for ``quantiles`` (an array) of ``n`` sorted values: its virtual index, its bounds
    and its gamma, so :func:`quantile_from_neighbours` of the two order statistics is numpy's
    quantile bit for bit (tests)."""
    virtual = (n - 1) * np.asarray(quantiles, dtype=float)
    prev = np.floor(virtual)
    nxt = prev + 1
    above, below = virtual >= n - 1, virtual < 0
    prev[above], nxt[above] = n - 1, n - 1
    prev[below], nxt[below] = 0, 0
    gamma = virtual - np.where(above, -1, prev)  # numpy's gamma (its 'above' index is -1)
    return prev.astype(np.int64), nxt.astype(np.int64), gamma


def quantile_from_neighbours(lower, upper, gamma) -> np.ndarray:
    """numpy's two-sided linear interpolation between neighbouring order statistics."""
    a, b = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    diff = b - a
    return np.where(gamma >= 0.5, b - diff * (1 - gamma), a + diff * gamma)
