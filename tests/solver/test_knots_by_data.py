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
    from mcsweep.solver.attitude_spline import _merge_sparse_segments, live_segments

    return _merge_sparse_segments(live_segments(start, end, *gaps, min_gap_days=0.5), SortedEpochs(t), per_knot)[0]
