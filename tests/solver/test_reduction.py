"""The fixed summation tree of mcsweep.solver.reduction: chunks of aligned runs of blocks give
the bits of the block-by-block sum, whatever the chunk sizes and the workers' shares."""

from __future__ import annotations

import numpy as np
import pytest

from mcsweep.solver.reduction import chunk_ranges, pairwise_sum, run_level


@pytest.mark.parametrize("n_blocks", [1, 2, 7, 46, 64, 101])
def test_chunks_of_aligned_runs_sum_to_the_same_bits_as_the_blocks(n_blocks):
    rng = np.random.default_rng(n_blocks)
    # summands over 16 orders of magnitude: any change of the tree changes the bits
    values = rng.normal(size=n_blocks) * 10.0 ** rng.uniform(-8, 8, n_blocks)
    ref = pairwise_sum(values)
    for shares in (1, 2, 3, 5):
        for cap in (None, 1, 2, 4, 16):
            ranges = chunk_ranges(n_blocks, cap, shares=shares)
            assert [lo for lo, _ in ranges] == sorted({lo for lo, _ in ranges})
            assert ranges[0][0] == 0 and ranges[-1][1] == n_blocks
            assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))
            for lo, hi in ranges:  # aligned powers of two, within the cap
                size = hi - lo
                assert size & (size - 1) == 0 and lo % size == 0 and (cap is None or size <= cap)
            got = pairwise_sum([pairwise_sum(values[lo:hi]) for lo, hi in ranges],
                               levels=[run_level(lo, hi) for lo, hi in ranges])
            assert got == ref
    # the tree decides the bits (so the equalities above can fail): (1e16 + 1) + (-1e16 + 1)
    # rounds to 0 where a left-to-right sum gives 1
    assert pairwise_sum([1e16, 1.0, -1e16, 1.0]) == 0.0 and ((1e16 + 1.0) - 1e16) + 1.0 == 1.0


def test_shares_are_equal_and_cut_where_the_workers_meet():
    ranges = chunk_ranges(46, None, shares=2)
    assert (23, 24) in ranges and any(hi == 23 for _, hi in ranges)  # no chunk straddles the share boundary
    assert len(ranges) <= 2 * 6  # a few runs per share (at most log2 of its size + 1 each)


def test_a_misaligned_run_is_refused():
    with pytest.raises(ValueError, match="does not start at a multiple"):
        pairwise_sum([1.0, 2.0], levels=[0, 1])  # a run of 2 blocks starting at block 1
