"""Confidence-region tools against closed forms, Monte Carlo and invariants."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import stats

from mcsweep.astrometry.confidence import (
    chi2_threshold,
    ellipse_semi_axes,
    error_percentile,
    fraction_inside,
    inside,
    inside_counts,
    mahalanobis_sq,
)
from mcsweep.errors import UserInputError

#: Relative agreement with closed forms (dimensionless).
CLOSED_FORM_RTOL = 1e-12
#: Monte Carlo deviations allowed, in binomial standard errors.
MC_MAX_Z = 4.0


def _random_cov2(rng, n):
    angle = rng.uniform(0, np.pi, n)
    lam = rng.uniform(0.01, 100.0, (n, 2))  # mas^2, axis ratios up to 1e4
    c, s = np.cos(angle), np.sin(angle)
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    return np.einsum("nij,nj,nkj->nik", R, lam, R)


def test_threshold_closed_forms():
    # Paper Sect. 2.4: -2 ln(1 - 0.9) = 4.605.
    assert chi2_threshold(0.9) == pytest.approx(4.605170185988091, rel=CLOSED_FORM_RTOL)
    for p in (0.1, 0.5, 0.8, 0.95, 0.99, 0.9999):
        assert chi2_threshold(p, dof=2) == pytest.approx(-2 * np.log1p(-p), rel=CLOSED_FORM_RTOL)
        # 1 dof: the square of the two-sided normal quantile.
        assert chi2_threshold(p, dof=1) == pytest.approx(stats.norm.ppf(0.5 + p / 2) ** 2, rel=1e-9)
    assert np.sqrt(chi2_threshold(0.9)) == pytest.approx(2.146, abs=5e-4)  # paper: ~2.146


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.2, 1.5, float("nan"), "ninety"])
def test_probability_is_validated_everywhere(bad):
    d, c = np.zeros((1, 2)), np.eye(2)[None]
    for call in (lambda: chi2_threshold(bad), lambda: inside(d, c, bad),
                 lambda: fraction_inside(d, c, bad), lambda: ellipse_semi_axes(c, bad)):
        with pytest.raises(UserInputError, match=r"P=.*strictly between 0 and 1") as err:
            call()
        assert "\n" not in str(err.value)


def test_mahalanobis_matches_explicit_inverse():
    rng = np.random.default_rng(1)
    cov = _random_cov2(rng, 500)
    d = rng.normal(size=(500, 2))
    expected = np.einsum("ni,nij,nj->n", d, np.linalg.inv(cov), d)
    np.testing.assert_allclose(mahalanobis_sq(d, cov), expected, rtol=1e-9)
    bad = np.array([[[1.0, 2.0], [2.0, 1.0]], [[np.nan, 0], [0, 1]]])  # indefinite, NaN
    assert np.all(np.isnan(mahalanobis_sq(np.ones((2, 2)), bad)))
    assert not inside(np.ones((2, 2)), bad, 0.9).any()


@pytest.mark.parametrize("p", [0.5, 0.9, 0.99])
def test_fraction_inside_of_gaussian_errors_is_p(p):
    rng = np.random.default_rng(2)
    n = 20000
    cov = _random_cov2(rng, n)
    d = np.einsum("nij,nj->ni", np.linalg.cholesky(cov), rng.normal(size=(n, 2)))
    frac = fraction_inside(d, cov, p)
    assert abs(frac - p) < MC_MAX_Z * np.sqrt(p * (1 - p) / n)
    assert frac == pytest.approx(np.mean(inside(d, cov, p)))
    # Errors twice as large as stated fall inside much less often.
    assert fraction_inside(2 * d, cov, p) < p - 0.1


def test_fraction_inside_ignores_flagged_rows():
    d = np.array([[0.1, 0.0], [np.nan, np.nan], [10.0, 0.0]])
    cov = np.array([np.eye(2), np.full((2, 2), np.nan), np.eye(2)])
    assert fraction_inside(d, cov, 0.9) == 0.5
    assert np.isnan(fraction_inside(d[1:2], cov[1:2], 0.9))


def test_inside_counts_states_the_nan_rule():
    # Q = r^2 for a unit covariance: r = 2 is inside the 90 % ellipse (k = 4.605), r = 3 is not;
    # a non-positive-definite covariance and a NaN error have no region and leave the denominator.
    d = np.array([[2.0, 0.0], [0.0, 3.0], [np.nan, 0.0], [0.1, 0.0]])
    cov = np.array([np.eye(2), np.eye(2), np.eye(2), -np.eye(2)])
    assert inside_counts(d, cov, 0.9) == (1, 2)
    assert inside(d, cov, 0.9).tolist() == [True, False, False, False]


def test_semi_axes_match_eigen_decomposition():
    rng = np.random.default_rng(3)
    cov = _random_cov2(rng, 200)
    k = -2 * np.log(1 - 0.8)
    lam = np.linalg.eigvalsh(cov)
    a, b = ellipse_semi_axes(cov, 0.8)
    np.testing.assert_allclose(a, np.sqrt(k * lam[:, 1]), rtol=1e-10)
    np.testing.assert_allclose(b, np.sqrt(k * lam[:, 0]), rtol=1e-9)
    a, b = ellipse_semi_axes(np.diag([4.0, 1.0])[None], 0.9)
    np.testing.assert_allclose([a[0], b[0]], [2 * np.sqrt(4.605170185988091), np.sqrt(4.605170185988091)])


@given(angle=st.floats(0, np.pi), l1=st.floats(1e-4, 1e4), l2=st.floats(1e-4, 1e4), p=st.floats(0.01, 0.999))
def test_ellipse_invariants(angle, l1, l2, p):
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])
    cov = (R @ np.diag([l1, l2]) @ R.T)[None]
    k = -2 * np.log1p(-p)
    a, b = ellipse_semi_axes(cov, p)
    assert a[0] >= b[0] > 0
    assert a[0] * b[0] == pytest.approx(k * np.sqrt(l1 * l2), rel=1e-8)
    assert a[0] ** 2 + b[0] ** 2 == pytest.approx(k * (l1 + l2), rel=1e-8)
    # The end of the semi-major axis lies on the boundary Q = k.
    major = R[:, 0] if l1 >= l2 else R[:, 1]
    assert mahalanobis_sq((a[0] * major)[None], cov)[0] == pytest.approx(k, rel=1e-6)


def test_error_percentile_matches_rayleigh_quantiles():
    rng = np.random.default_rng(4)
    sigma = 3.0  # mas, isotropic
    d = rng.normal(0, sigma, size=(200000, 2))
    for q in (50.0, 90.0, 99.0):
        expected = sigma * np.sqrt(-2 * np.log1p(-q / 100))  # Rayleigh distribution
        assert error_percentile(d, q) == pytest.approx(expected, rel=0.01)
    d[:10] = np.nan
    assert np.isfinite(error_percentile(d, 90))
    for bad in (-1, 101, "x"):
        with pytest.raises(UserInputError, match="percentile"):
            error_percentile(d, bad)


def test_binomial_interval_matches_scipy_clopper_pearson():
    from scipy.stats import binomtest

    from mcsweep.astrometry.confidence import binomial_interval

    for k, n in ((0, 10), (9, 10), (10, 10), (450, 500), (1800, 2000)):
        ci = binomtest(k, n).proportion_ci(confidence_level=0.68, method="exact")
        lo, hi = binomial_interval(k, n, 0.68)
        np.testing.assert_allclose([lo, hi], [ci.low, ci.high], rtol=1e-9)
    assert np.isnan(binomial_interval(0, 0)[0])
