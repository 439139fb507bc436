"""The fixed summation tree of mcsweep.solver.reduction: chunks of aligned runs of blocks give
the bits of the block-by-block sum, whatever the chunk sizes and the workers' shares."""

from __future__ import annotations

import numpy as np
import pytest

from mcsweep.solver.reduction import LEAF_RATIO, MIN_LEAVES, chunk_ranges, leaf_blocks, pairwise_sum, run_level


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


@pytest.mark.parametrize("n_blocks,leaf", [(46, 4), (47, 4), (13, 2), (64, 8), (5, 4)])
def test_chunks_of_leaves_keep_both_trees(n_blocks, leaf):
    # Chunks of whole leaves (the last may be short): per-block numbers still sum to the bits of
    # the blocks' tree, and the leaves' vectors (a leaf: its blocks added left to right) to the
    # bits of the leaves' tree, whatever the chunk sizes and the workers' shares.
    rng = np.random.default_rng(n_blocks + leaf)
    values = rng.normal(size=n_blocks) * 10.0 ** rng.uniform(-8, 8, n_blocks)
    ref = pairwise_sum(values)
    leaf_sums = []
    for lo in range(0, n_blocks, leaf):
        acc = 0.0
        for v in values[lo:lo + leaf]:
            acc += v
        leaf_sums.append(acc)
    ref_leaves = pairwise_sum(leaf_sums)
    for shares in (1, 2, 3):
        for cap in (None, leaf, 2 * leaf, 4 * leaf):
            ranges = chunk_ranges(n_blocks, cap, shares=shares, leaf=leaf)
            assert ranges[0][0] == 0 and ranges[-1][1] == n_blocks
            assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))
            assert all(lo % leaf == 0 for lo, _ in ranges)
            got = pairwise_sum([pairwise_sum(values[lo:hi]) for lo, hi in ranges],
                               levels=[run_level(lo, hi) for lo, hi in ranges])
            assert got == ref
            per_chunk = [pairwise_sum(leaf_sums[lo // leaf:-(-hi // leaf)]) for lo, hi in ranges]
            got = pairwise_sum(per_chunk, levels=[run_level(lo // leaf, -(-hi // leaf)) for lo, hi in ranges])
            assert got == ref_leaves


def test_leaf_size_follows_the_attitude_unknowns_per_block():
    # 3 h knots at the paper's sizes: 46 blocks of ~8.4e5 measurements, 9e3 attitude unknowns
    assert leaf_blocks(46, 46 * 840_000, 9_000) == 1
    # 30 s knots (AGIS's, at the paper's sizes): 2.3e6 unknowns; LEAF_RATIO * 2.3e6 needs 8 blocks, but 46 blocks
    # must keep MIN_LEAVES leaves: 4 (12 leaves)
    assert LEAF_RATIO * 2_300_000 > 4 * 840_000 and MIN_LEAVES == 8
    assert leaf_blocks(46, 46 * 840_000, 2_300_000) == 4
    assert leaf_blocks(1000, 1000 * 840_000, 2_300_000) == 8  # enough blocks: the ratio decides
    assert leaf_blocks(3, 3 * 100, 10**6) == 1 and leaf_blocks(0, 0, 10) == 1
