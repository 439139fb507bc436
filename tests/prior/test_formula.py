"""sigma_F90 of the paper (Eqs. 14-17), checked against hand evaluations."""

import numpy as np
import pytest

from mcsweep.errors import UserInputError
from mcsweep.prior import (
    G_FIT_MAX,
    G_FIT_MIN,
    PAPER_COEFFICIENTS,
    s_coefficients,
    sigma_f90,
    sigma_from_coefficients,
)

#: Hand evaluations below keep 6-7 significant digits in log10 sigma.
HAND_RTOL = 1e-6
#: Same formula through numpy's array and scalar code paths: they may differ in the last
#: bits (SIMD vs scalar pow/log10; 1.4195796959515958 vs 1.419579695951596 seen with numpy 2.4).
RTOL_PATHS = 1e-13


def _deg(x):
    return np.radians(x)


def test_hand_evaluation_galactic_centre_direction_g15():
    # s0(15) = 2.187 - 0.2547*15 + 0.006382*225 = 2.187 - 3.8205 + 1.43595 = -0.19755
    # s2(15) = 0.031 - 0.0062*15 = -0.062;  l = b = 0: |sin b| = 0, cos b cos l = 1
    assert sigma_f90(0.0, 0.0, 15.0) == pytest.approx(10 ** (-0.19755 - 0.062), rel=HAND_RTOL)


def test_hand_evaluation_table1_direction_g15():
    # Paper Table 1 direction l = 245.7, b = +46.5.
    # s1(15) = 0.114 - 0.0579*15 + 0.01369*225 - 0.000506*3375
    #        = 0.114 - 0.8685 + 3.08025 - 1.70775 = 0.618
    log_sigma = -0.19755 + 0.618 * abs(np.sin(_deg(46.5))) - 0.062 * np.cos(_deg(46.5)) * np.cos(_deg(245.7))
    assert sigma_f90(245.7, 46.5, 15.0) == pytest.approx(10**log_sigma, rel=HAND_RTOL)
    assert sigma_f90(245.7, 46.5, 15.0) == pytest.approx(1.855, rel=1e-3)


def test_hand_evaluation_g10_and_g20():
    # G = 10: s0 = 2.187 - 2.547 + 0.6382 = 0.2782; s1 = 0.114 - 0.579 + 1.369 - 0.506 = 0.398
    # l = 90 (cos l = 0), b = -30 (|sin b| = 0.5): log10 sigma = 0.2782 + 0.199 = 0.4772
    assert sigma_f90(90.0, -30.0, 10.0) == pytest.approx(10**0.4772, rel=HAND_RTOL)
    # G = 20: s0 = 2.187 - 5.094 + 2.5528 = -0.3542; s1 = 0.114 - 1.158 + 5.476 - 4.048 = 0.384
    # b = 90: log10 sigma = -0.3542 + 0.384 = 0.0298 (the s2 term vanishes with cos b)
    assert sigma_f90(180.0, 90.0, 20.0) == pytest.approx(10**0.0298, rel=HAND_RTOL)


def test_fainter_than_20_uses_g20():
    l, b = np.array([10.0, 200.0]), np.array([5.0, -60.0])
    np.testing.assert_array_equal(sigma_f90(l, b, 20.7), sigma_f90(l, b, 20.0))
    np.testing.assert_array_equal(sigma_f90(l, b, 25.0), sigma_f90(l, b, G_FIT_MAX))


def test_brighter_than_6_choices():
    # G = 3, l = b = 0. Extrapolated: s0(3) = 2.187 - 0.7641 + 0.057438 = 1.480338,
    # s2(3) = 0.031 - 0.0186 = 0.0124 -> log10 sigma = 1.492738.
    assert sigma_f90(0.0, 0.0, 3.0) == pytest.approx(10**1.492738, rel=HAND_RTOL)
    # Clamped: s0(6) = 2.187 - 1.5282 + 0.229752 = 0.888552, s2(6) = -0.0062 -> 0.882352.
    assert sigma_f90(0.0, 0.0, 3.0, bright="clamp") == pytest.approx(10**0.882352, rel=HAND_RTOL)
    assert sigma_f90(0.0, 0.0, G_FIT_MIN, bright="clamp") == sigma_f90(0.0, 0.0, G_FIT_MIN)
    # The extrapolation keeps growing towards bright stars at every latitude (conservative).
    g = np.linspace(-1.0, 6.0, 50)
    for b in (0.0, 30.0, 90.0):
        assert np.all(np.diff(sigma_f90(0.0, b, g)) < 0)
    with pytest.raises(UserInputError, match="bright"):
        sigma_f90(0.0, 0.0, 3.0, bright="hipparcos")


def test_broadcasting_and_array_inputs():
    l = np.array([[0.0], [120.0], [240.0]])
    b = np.array([-60.0, -10.0, 0.0, 45.0])
    out = sigma_f90(l, b, 17.0)
    assert out.shape == (3, 4)
    for i in range(3):
        for j in range(4):
            assert out[i, j] == pytest.approx(sigma_f90(l[i, 0], b[j], 17.0), rel=RTOL_PATHS, abs=0)
    g = np.array([8.0, 12.0, 16.0, 19.5])
    assert sigma_f90(30.0, 10.0, g).shape == (4,)


def test_coefficients_table_and_reuse_for_other_fits():
    assert PAPER_COEFFICIENTS["s0"] == (2.187, -0.2547, 0.006382)
    assert PAPER_COEFFICIENTS["s1"] == (0.114, -0.0579, 0.01369, -0.000506)
    assert PAPER_COEFFICIENTS["s2"] == (0.031, -0.0062)
    with pytest.raises(TypeError):
        PAPER_COEFFICIENTS["s0"] = (0.0,)  # read-only
    s0, s1, s2 = s_coefficients(15.0)
    assert (s0, s1, s2) == pytest.approx((-0.19755, 0.618, -0.062), abs=1e-12)
    # Custom coefficients: log10 sigma = 0.1 G + 0.5 |sin b| + 0.2 cos b cos l.
    custom = {"s0": (0.0, 0.1), "s1": (0.5,), "s2": (0.2,)}
    expected = 10 ** (1.0 + 0.25 + 0.2 * np.cos(_deg(30.0)) * 0.5)  # G = 10, b = 30, l = 60
    assert sigma_from_coefficients(60.0, 30.0, 10.0, custom) == pytest.approx(expected, rel=1e-12)
    with pytest.raises(UserInputError, match="s2"):
        sigma_from_coefficients(0.0, 0.0, 10.0, {"s0": (1.0,), "s1": (0.0,)})
    with pytest.raises(UserInputError, match="NaN"):
        sigma_f90(0.0, 0.0, np.nan)


#: Two evaluations of the same Eq. 14 (interpolation at or between nodes): rounding only.
NODE_RTOL = 1e-12


def test_eq14_between_g_nodes_is_linear_in_its_terms_and_constant_beyond():
    from mcsweep.prior.formula import sigma_from_nodes, sigma_from_coefficients

    g_nodes = np.array([6.5, 7.5, 8.5])
    s_nodes = np.array([[1.0, 0.2, 0.05], [0.8, 0.1, 0.0], [0.5, -0.1, 0.02]])
    l_deg, b_deg = np.array([30.0, 200.0]), np.array([-40.0, 10.0])
    at = sigma_from_nodes(l_deg, b_deg, 7.5, g_nodes, s_nodes)
    # At a node: Eq. 14 with that node's terms (constant polynomials).
    const = {k: (v,) for k, v in zip(("s0", "s1", "s2"), s_nodes[1])}
    np.testing.assert_allclose(at, sigma_from_coefficients(l_deg, b_deg, 7.5, const), rtol=NODE_RTOL)
    # Half-way: the terms' mean, so log10 sigma is the mean of the two nodes' log10 sigma.
    half = sigma_from_nodes(l_deg, b_deg, 8.0, g_nodes, s_nodes)
    ends = [sigma_from_nodes(l_deg, b_deg, g, g_nodes, s_nodes) for g in (7.5, 8.5)]
    np.testing.assert_allclose(np.log10(half), np.mean(np.log10(ends), axis=0), rtol=NODE_RTOL)
    # Beyond the outer nodes: the outer node's value.
    np.testing.assert_allclose(sigma_from_nodes(l_deg, b_deg, 20.0, g_nodes, s_nodes), ends[1], rtol=NODE_RTOL)
    np.testing.assert_allclose(sigma_from_nodes(l_deg, b_deg, 3.0, g_nodes, s_nodes),
                               sigma_from_nodes(l_deg, b_deg, 6.5, g_nodes, s_nodes), rtol=NODE_RTOL)
