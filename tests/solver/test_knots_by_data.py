"""Knots placed by the data (solver.attitude_spline, ``transits_per_knot``) against numpy's
quantiles of the sorted epochs, and from epochs that never meet in one array."""

import numpy as np
import pytest

from mcsweep.solver.attitude_spline import AttitudeSpline, SortedEpochs


def _reference_knots(segments, t, per_knot):
    """Each (already merged) segment's ends and inner knots as numpy.quantile gives them."""
    out, segs = [], []
    for a, b in segments:
        ts = t[np.searchsorted(t, a, "left"):np.searchsorted(t, b, "right")]
        if ts.size and ts[-1] > ts[0]:
            a, b = ts[0], ts[-1]
        n_int = max(1, int(round(ts.size / per_knot)))
        inner = np.quantile(ts, np.arange(1, n_int) / n_int) if ts.size else np.zeros(0)
        out.append(np.unique(np.concatenate([[a], inner[(inner > a) & (inner < b)], [b]])))
        segs.append((a, b))
    return out, np.array(segs)


class _Split:
    """Epochs held in several sorted pieces, answering SortedEpochs' questions by sums and
    a merge of the pieces (what a cluster's workers do, without the cluster)."""

    def __init__(self, pieces):
        self.pieces = [np.sort(p) for p in pieces]

    @property
    def size(self):
        return sum(p.size for p in self.pieces)

    def searchsorted(self, x, side):
        return sum(np.searchsorted(p, x, side) for p in self.pieces)

    def values(self, ranks):
        return np.sort(np.concatenate(self.pieces))[np.asarray(ranks)]


@pytest.mark.parametrize("per_knot", [1.0, 3.0, 25.0])
def test_knots_are_numpys_quantiles_of_each_segments_epochs(per_knot):
    rng = np.random.default_rng(int(per_knot))
    start, end = 100.0, 130.0
    gaps = (np.array([104.0, 110.0, 110.3, 120.0]), np.array([105.0, 110.2, 111.0, 120.05]))
    t = np.concatenate([rng.uniform(start, end, 3000), np.full(20, 115.5)])  # ties
    live = np.ones(t.size, bool)
    for a, b in zip(*gaps):
        live &= ~((t >= a) & (t < b))
    t = t[live]
    spline = AttitudeSpline(start, end, 0.5, gaps=gaps, epochs=t, transits_per_knot=per_knot)
    expected, segs = _reference_knots(_merged(start, end, gaps, t, per_knot), np.sort(t), per_knot)
    np.testing.assert_array_equal(spline.segments, segs)
    for got, ref in zip(spline.segment_knots, expected, strict=True):
        np.testing.assert_array_equal(got[3:-3], ref)
    split = AttitudeSpline(start, end, 0.5, gaps=gaps, epochs=_Split(np.array_split(rng.permutation(t), 7)),
                           transits_per_knot=per_knot)
    for a, b in zip(split.segment_knots, spline.segment_knots, strict=True):
        np.testing.assert_array_equal(a, b)


def _merged(start, end, gaps, t, per_knot):
    """The segments after the sparse ones are joined (the spline's own rule, with the epochs
    as one array): the reference's input."""
    from mcsweep.solver.attitude_spline import merge_sparse_segments, live_segments

    return merge_sparse_segments(live_segments(start, end, *gaps, min_gap_days=0.5), SortedEpochs(t), per_knot)[0]


#: Tolerance on a uniform knot interval in a dense stretch: the knots divide the segment's
#: density integral into round(integral) equal parts, so a spacing differs from the interval
#: by at most half a part over the segment's whole integral (here < 1e-3), plus rounding.
UNIFORM_RTOL = 2e-3


def test_uniform_knots_keep_the_interval_where_the_data_are_dense_and_the_count_where_they_are_sparse():
    # knot_rule='uniform' (AGIS's uniform knots, lengthened only where too few epochs fall):
    # against the closed forms of its two regimes on a stretch of 20 epochs per interval
    # followed by one of 1 per interval, K = 5.
    rng = np.random.default_rng(3)
    D, K = 1.0, 5.0
    dense = np.sort(rng.uniform(0.0, 1000.0, 20000))
    sparse = np.sort(rng.uniform(1000.0, 3000.0, 2000))
    t = np.concatenate([dense, sparse])
    spline = AttitudeSpline(0.0, 3000.0, D, epochs=t, transits_per_knot=K, knot_rule="uniform")
    knots = spline.segment_knots[0][3:-3]
    step = np.diff(knots)
    in_dense = knots[1:] <= 999.0
    in_sparse = knots[:-1] >= 1001.0
    # dense: one knot per interval D, whatever the epochs do inside it
    np.testing.assert_allclose(step[in_dense], D, rtol=UNIFORM_RTOL)
    # sparse: the density is the epochs' count per bin / K, so each interval holds K epochs but
    # for where a knot falls within its bin (linear there): off by at most the epochs of the
    # two bins its ends lie in (Poisson, 1 per bin on average here: 4 or more in 2 % of the bins)
    counts = np.histogram(t, knots)[0][in_sparse]
    assert np.mean(np.abs(counts - K) <= 2) > 0.95 and np.abs(counts - K).max() <= 4  # measured: all, 2
    assert abs(step[in_sparse].mean() - K * D) < 0.05 * K * D
    # never much finer than D: a spacing is D times the part over the bins' density <= 1
    assert step.min() > D * (1 - UNIFORM_RTOL)
    # the count rule on the same epochs: K per interval everywhere, so a fifth of D where dense
    counted = np.diff(AttitudeSpline(0.0, 3000.0, D, epochs=t, transits_per_knot=K).segment_knots[0][3:-3])
    assert np.median(counted[:3000]) < 0.3 * D
    # epochs in pieces give the same bits (a cluster's workers, primary_knots.ClusterEpochs)
    split = AttitudeSpline(0.0, 3000.0, D, epochs=_Split(np.array_split(rng.permutation(t), 5)),
                           transits_per_knot=K, knot_rule="uniform")
    np.testing.assert_array_equal(split.segment_knots[0], spline.segment_knots[0])


def test_uniform_knots_count_the_epochs_at_a_segment_s_start():
    # A segment starts at its first epoch: 40 epochs tied there make its first bin dense, so
    # its first knot follows one interval D later (against 40 / K = 8 intervals' worth of
    # density missing if the start's ties were not counted), then one per K sparse epochs.
    D, K = 1.0, 5.0
    t = np.concatenate([np.full(40, 10.0), 10.5 + np.arange(50.0)])  # then one epoch per D
    spline = AttitudeSpline(0.0, 70.0, D, epochs=t, transits_per_knot=K, knot_rule="uniform")
    knots = spline.segment_knots[0][3:-3]
    assert knots[0] == 10.0 and spline.segments[0, 0] == 10.0
    # the integral: 1 (first bin, 40 + 1 epochs) + 49 bins of 1 / K each = 10.8 -> 11 parts
    assert knots.size - 1 == 11
    np.testing.assert_allclose(knots[1], 10.0 + D * 10.8 / 11, rtol=1e-12)


def test_the_config_accepts_the_spline_s_knot_rules():
    from mcsweep.solver.attitude_spline import KNOT_RULES
    from mcsweep.experiments.primary.conf import KNOT_RULES as accepted

    assert accepted == KNOT_RULES
    with pytest.raises(ValueError, match="knot_rule"):
        AttitudeSpline(0.0, 10.0, 1.0, epochs=np.linspace(0, 10, 50), transits_per_knot=5, knot_rule="agis")
