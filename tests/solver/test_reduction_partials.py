"""Partial sums of the fixed tree made where the runs are (solver.reduction.AlignedPartials):
their pairwise sum is the tree's over all runs, bit for bit, however the runs are shared out."""

import numpy as np
import pytest

from mcsweep.solver.reduction import AlignedPartials, chunk_ranges, pairwise_sum, run_level


@pytest.mark.parametrize("n_blocks, chunk, holders", [(37, 1, 3), (37, 4, 2), (64, 8, 3), (100, 2, 5), (5, 4, 2)])
def test_partials_sum_to_the_trees_bits(n_blocks, chunk, holders):
    rng = np.random.default_rng(n_blocks * chunk + holders)
    blocks = [rng.normal(0.0, 1.0, 50) * 10.0 ** rng.integers(-8, 8) for _ in range(n_blocks)]
    ranges = chunk_ranges(n_blocks, chunk)
    values = [pairwise_sum(blocks[lo:hi]) for lo, hi in ranges]
    levels = [run_level(lo, hi) for lo, hi in ranges]
    whole = pairwise_sum(blocks)
    assert np.array_equal(pairwise_sum(values, None, levels), whole)
    for owner in (lambda ci: ci % holders, lambda ci: ci * holders // len(ranges)):  # scattered or contiguous shares
        shares = [AlignedPartials() for _ in range(holders)]
        for ci, ((lo, _), lv, v) in enumerate(zip(ranges, levels, values)):
            shares[owner(ci)].push(lo, lv, v)
        parts = sorted((p for s in shares for p in s.partials), key=lambda p: p[0])
        got = pairwise_sum((p[2] for p in parts), None, (p[1] for p in parts))
        assert np.array_equal(got, whole)
        if owner(1) == owner(0) and len(ranges) > 4:
            assert len(parts) < len(ranges)  # contiguous shares send fewer sums
