"""The real-sky fractions carried over to the complete sky by colour
(experiments.real_sky_complete): the weighting against closed forms."""

import numpy as np
import pytest

from mcsweep.experiments.real_sky.complete import BP_RP_EDGES, carried_fraction, colour_class

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


def test_carried_quantile_against_hazen_and_a_two_value_closed_form():
    from mcsweep.experiments.real_sky.complete import carried_quantile

    values = np.random.default_rng(3).lognormal(1.0, 0.7, 501)
    classes = np.random.default_rng(4).integers(0, 3, values.size)
    own = np.bincount(classes, minlength=3)
    # each class weighted by its own share: the plain (Hazen) quantile of the values
    for q in (0.1, 0.5, 0.9):
        assert carried_quantile(values, classes, own, q) == pytest.approx(np.quantile(values, q, method="hazen"),
                                                                          rel=RTOL)
    # value 1 standing for 3 stars, value 2 for 1: the median lies a quarter of the way up
    assert carried_quantile([1.0, 2.0], [0, 1], [3, 1], 0.5) == pytest.approx(1.25, rel=RTOL)
    # a coloured class of the whole without values: no value; stars without colour (the last
    # class) unseen: shared out like the rest
    assert np.isnan(carried_quantile([1.0, 2.0], [0, 1], [3, 1, 2], 0.5))
    no_colour = np.zeros(len(BP_RP_EDGES) + 2)
    no_colour[[0, 1, -1]] = [3, 1, 40]
    assert carried_quantile([1.0, 2.0], [0, 1], no_colour, 0.5) == pytest.approx(1.25, rel=RTOL)
    assert carried_fraction([1, 0], [0, 1], no_colour)[0] == pytest.approx(0.75, rel=RTOL)
    # values of a class absent from the whole stand for no star
    assert carried_quantile([1.0, 5.0, 10.0], [0, 1, 2], [1, 0, 1], 0.5) == pytest.approx(5.5, rel=RTOL)


def test_classes_by_colour_within_half_magnitudes():
    from mcsweep.experiments.real_sky.complete import N_COLOUR_CLASSES, SUB_BINS, colour_magnitude_class

    assert SUB_BINS == 2
    got = colour_magnitude_class([0.0, 0.0, 1.2, np.nan, 1.2], [6.1, 6.6, 7.49, 7.99, 8.0], [(6, 7), (7, 8), (8, 9)])
    assert got.tolist() == [0, N_COLOUR_CLASSES, 3, 2 * N_COLOUR_CLASSES - 1, 3]
