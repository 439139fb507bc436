"""The real-sky fractions carried over to the complete sky by colour (issue 25;
experiments.real_sky_complete): the weighting against closed forms."""

import numpy as np
import pytest

from mcsweep.experiments.real_sky_complete import BP_RP_EDGES, carried_fraction, colour_class

#: Two exact evaluations of one weighted mean in floating point.
RTOL = 1e-12


def test_colour_classes_by_the_edges_and_one_for_no_colour():
    got = colour_class([-0.3, 0.5, 0.79, 1.1, 1.5, 2.5, np.nan])
    assert got.tolist() == [0, 1, 1, 3, 4, 5, len(BP_RP_EDGES) + 1]


def test_carried_fraction_weights_each_class_by_its_share_of_the_whole():
    # class 0: 8 of 10 solved stars inside, class 1: 1 of 4; the whole has 30 and 70 of them
    inside = np.r_[np.ones(8), np.zeros(2), np.ones(1), np.zeros(3)]
    classes = np.r_[np.zeros(10, int), np.ones(4, int)]
    f, sigma = carried_fraction(inside, classes, [30, 70])
    assert f == pytest.approx(0.3 * 0.8 + 0.7 * 0.25, rel=RTOL)
    assert sigma == pytest.approx(np.sqrt(0.3 ** 2 * 0.8 * 0.2 / 10 + 0.7 ** 2 * 0.25 * 0.75 / 4), rel=RTOL)
    # the solved stars' own mix: the plain fraction inside
    f_own, _ = carried_fraction(inside, classes, [10, 4])
    assert f_own == pytest.approx(inside.mean(), rel=RTOL)
    # a class of the whole without a solved star: no value
    assert np.isnan(carried_fraction(inside, classes, [30, 70, 5])[0])
    # a class of the solved stars absent from the whole weighs nothing
    assert carried_fraction(inside, classes, [30, 0])[0] == pytest.approx(0.8, rel=RTOL)
