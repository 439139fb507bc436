"""Radix selection of order statistics over chunks (solver.selection) against numpy's sort."""

import numpy as np
import pytest

from mcsweep.solver.selection import float_keys, median, quantile_from_neighbours, quantile_ranks, select

#: numpy's quantile and ours from the same two order statistics: the same formula, so
#: equal up to the last bit; a relative 1e-15 allows one rounding of difference.
RTOL_SAME_FORMULA = 1e-15


def _counts_of(chunks):
    from mcsweep.solver.selection import digit_counts

    return lambda queries: [digit_counts(c, queries) for c in chunks[::-1]]  # any order of the chunks


def _chunks(seed):
    rng = np.random.default_rng(seed)
    x = np.concatenate([rng.lognormal(3.0, 2.0, 5000), -rng.lognormal(0.0, 1.0, 300), np.zeros(50),
                        np.full(40, 7.25), [np.finfo(float).tiny, -0.0, 1e300, -1e300],
                        7.25 + np.arange(1, 30) * np.spacing(7.25)])  # neighbours in the last bit
    x = rng.permutation(x)
    return np.array_split(x, [3, 1000, 1001, 4321]), np.sort(x)


def test_keys_keep_the_order_of_the_values():
    x = _chunks(1)[1]
    x = x[x != 0]  # (-0.0 and 0.0 are equal values with two keys: -0.0 first)
    k = float_keys(x)
    np.testing.assert_array_equal(np.argsort(k, kind="stable"), np.argsort(x, kind="stable"))
    assert float_keys(np.array([-0.0]))[0] < float_keys(np.array([0.0]))[0]


@pytest.mark.parametrize("seed", [1, 2])
def test_order_statistics_are_numpys(seed):
    chunks, ordered = _chunks(seed)
    ranks = [0, 1, 17, 2710, 2711, len(ordered) // 2, len(ordered) - 1]
    assert select(_counts_of(chunks), ranks) == [float(ordered[r]) for r in ranks]
    with pytest.raises(ValueError, match="beyond"):
        select(_counts_of(chunks), [len(ordered)])


@pytest.mark.parametrize("n", [1, 2, 5, 5418, 5419])
def test_median_is_numpys_bit_for_bit(n):
    rng = np.random.default_rng(n)
    x = rng.lognormal(0.0, 1.0, n)
    x[: n // 3] = x[0]  # ties
    chunks = np.array_split(x, min(n, 7))
    assert median(_counts_of(chunks), n) == float(np.median(x))


@pytest.mark.parametrize("n", [1, 2, 3, 10, 997])
@pytest.mark.parametrize("quantile", [0.1, 0.5, 0.9, 0.9000000000000001])
def test_linear_quantile_is_numpys(n, quantile):
    x = np.sort(np.random.default_rng(n).lognormal(0, 1, n).astype(np.float32)).astype(float)
    v = (n - 1) * quantile
    lo, hi = int(np.floor(v)), min(int(np.floor(v)) + 1, n - 1)
    prev, nxt, gamma = quantile_ranks(n, [quantile])
    assert (int(prev[0]), int(nxt[0])) == (lo, hi)
    assert quantile_from_neighbours(x[lo], x[hi], gamma)[0] == pytest.approx(np.quantile(x, quantile),
                                                                       rel=RTOL_SAME_FORMULA, abs=0)
