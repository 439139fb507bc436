"""Normal equations of stars sharing one design, in factored form, against the explicit path."""

import numpy as np
import pytest

from mcsweep.astrometry.linalg import PIVOT_TOLERANCE
from mcsweep.astrometry.prior_scan import prior_scan
from mcsweep.astrometry.scan_kernel import normal_noise, reduce_normals
from mcsweep.astrometry.shared_design import SharedDesignNormals
from mcsweep.astrometry.solve import prior_diagonal

#: The compiled pass forms N and b in another order than the explicit matrices: the two
#: solutions agree to rounding, relative to each star's largest covariance element (and
#: position errors relative to the larger of their size and their standard deviation).
RTOL_FACTORED = 1e-9
#: Where N0 + N_p is ill-conditioned, the bound kappa * eps times the few dozen roundings of
#: either path (as in tests/astrometry/test_prior_scan.py).
FORWARD_FACTOR = 1e3


def _design(rng, k):
    return rng.normal(size=(2 * k, 5)) * np.array([10.0, 10.0, 8.0, 3.0, 3.0])


@pytest.mark.parametrize("k", [1, 3, 5, 12])
def test_factored_reduction_equals_the_reduction_of_the_matrices(k):
    rng = np.random.default_rng(k)
    n = 700
    weights = [rng.uniform(0.5, 5.0, n), rng.uniform(0.1, 1.0, n)]
    truth = rng.normal(size=(3, n)) * np.array([[2.0], [20.0], [20.0]])
    normals = SharedDesignNormals.simulate(_design(rng, k), weights, truth, np.random.default_rng(3))
    assert normals.unit.shape == (2, min(k, 5), 5) and normals.noise.shape == (5, n)
    fused = normals.prior_scan(10.0)
    ref = prior_scan(*normals.matrices(), 10.0)
    np.testing.assert_array_equal(fused.ok, ref.ok)
    # Compared where they are unique: the solution at each prior (the eigenvectors of a
    # singular Schur complement, one or two transits, are any basis of its null space).
    n0 = normals.matrices()[0]
    ok = ref.ok
    for sigma in np.geomspace(0.01, 1000.0, 7):
        (d_f, c_f), (d_r, c_r) = fused.position(sigma), ref.position(sigma)
        # With one or two transits N0 is singular and a loose prior leaves N0 + N_p
        # ill-conditioned: two float64 paths then agree to ~ kappa * eps, no better.
        kappa = np.linalg.cond(n0[ok] + np.diag(prior_diagonal(sigma, 10.0)))
        tol = np.maximum(RTOL_FACTORED, FORWARD_FACTOR * kappa * np.finfo(float).eps)
        c_scale = np.abs(c_r[ok]).reshape(-1, 4).max(axis=1)
        assert np.all(np.abs(c_f[ok] - c_r[ok]).reshape(-1, 4).max(axis=1) <= tol * c_scale)
        # a position error relative to its own uncertainty (what the ellipse test uses)
        d_scale = np.maximum(np.abs(d_r[ok]).max(axis=1), np.sqrt(c_scale))
        assert np.all(np.abs(d_f[ok] - d_r[ok]).max(axis=1) <= tol * d_scale)


def test_normal_matrices_are_the_weighted_design_products():
    rng = np.random.default_rng(1)
    a = _design(rng, 7)
    w = [rng.uniform(0.5, 5.0, 4), rng.uniform(0.1, 1.0, 4)]
    n0, _ = SharedDesignNormals.simulate(a, w, np.zeros((3, 4)), rng).matrices()
    for i in range(4):
        ai = a * np.repeat([w[0][i], w[1][i]], 7)[:, None]
        np.testing.assert_allclose(n0[i], ai.T @ ai, rtol=1e-12, atol=1e-12 * np.abs(ai.T @ ai).max())


def test_shapes_that_do_not_fit_are_refused():
    with pytest.raises(ValueError, match="multiple of the number of weight blocks"):
        SharedDesignNormals.simulate(np.zeros((5, 5)), [np.ones(3), np.ones(3)], np.zeros((3, 3)),
                                     np.random.default_rng(0))


@pytest.mark.parametrize("blocks", [1, 2])
@pytest.mark.parametrize("k", [1, 4, 9])
def test_fused_formation_is_the_reduction_of_the_same_sums_bit_for_bit(blocks, k):
    """The compiled pass forms each star's N and b in registers; formed here in numpy in the
    same order (blocks summed from zero; the signal N x, then the noise of normal_noise) and
    reduced by reduce_normals, every output is the same bit for bit, signed zeros included."""
    rng = np.random.default_rng(10 * k + blocks)
    n = 600  # more than two of the kernel's blocks of stars
    weights = [rng.uniform(0.5, 5.0, n), rng.uniform(0.1, 1.0, n)][:blocks]
    truth = rng.normal(size=(3, n)) * np.array([[2.0], [20.0], [20.0]])
    truth[:, :5] = 0.0  # stars with zero signal
    normals = SharedDesignNormals.simulate(_design(rng, k)[:blocks * k], weights, truth, np.random.default_rng(4))
    N = np.zeros((5, 5, n))
    b = np.zeros((5, n))
    for u, w in zip(normals.unit, normals.weight):
        nu = np.zeros((5, 5))
        for row in u:
            nu = nu + row[:, None] * row[None, :]
        N = N + nu[:, :, None] * (w * w)
        b = b + ((nu[:, 2, None] * truth[0] + nu[:, 3, None] * truth[1]) + nu[:, 4, None] * truth[2]) * (w * w)
    noise = np.empty((5, n))
    normal_noise(N, normals.noise, PIVOT_TOLERANCE, noise)
    ref = [np.empty((2, n)), np.empty((3, n)), np.empty((2, 3, n)), np.empty((3, n)), np.empty((3, n)),
           np.empty(n, dtype=bool)]
    reduce_normals(N, b + noise, 10.0, PIVOT_TOLERANCE, *ref)
    fused = normals.prior_scan(10.0)
    for name, r in zip(("x0", "ainv", "g", "c", "lam", "ok"), ref):
        got = getattr(fused, name)
        np.testing.assert_array_equal(got, r, err_msg=name)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(r), err_msg=name)


#: Standard deviations of a sample covariance element allowed before a test fails (a
#: correct draw fails one element in ~1e6 at 5 sigma).
COVARIANCE_SIGMAS = 5.0


def _zero_parallax_design(rng, k):
    a = _design(rng, k)
    a[:, 2] = 0.0  # no parallax factor: S's first pivot is zero, the others are not
    return a


@pytest.mark.parametrize("make", [_design, _zero_parallax_design], ids=["random", "no-parallax-factor"])
@pytest.mark.parametrize("blocks", [1, 2])
@pytest.mark.parametrize("k", [1, 2, 3, 8])
def test_noise_has_the_covariance_of_the_normal_matrix(k, blocks, make):
    """b - N x is Gaussian with covariance N (the distribution of sum U' e / sigma over the
    measurements): the sample covariance of many stars with the same N against N, element by
    element within COVARIANCE_SIGMAS of the Wishart spread."""
    rng = np.random.default_rng(10 * k + blocks)
    n = 40_000
    a = make(rng, k)[:blocks * k]
    weights = [np.full(n, 2.0), np.full(n, 0.5)][:blocks]
    normals = SharedDesignNormals.simulate(a, weights, np.zeros((3, n)), np.random.default_rng(5 + k))
    n0, b0 = normals.matrices()
    cov = n0[0]
    if k * blocks == 1:  # one AL row: the position is not determined, the star gets no noise
        assert np.linalg.matrix_rank(cov[:2, :2]) == 1 and np.all(b0 == 0.0)
        return
    sample = b0.T @ b0 / n
    # Var of a sample covariance element of a Gaussian: (C_ii C_jj + C_ij^2) / n
    sd = np.sqrt((np.outer(np.diag(cov), np.diag(cov)) + cov ** 2) / n)
    assert np.all(np.abs(sample - cov) <= COVARIANCE_SIGMAS * sd + 1e-12 * np.abs(cov).max())
    if make is _zero_parallax_design:
        assert np.all(b0[:, 2] == 0.0)  # nothing measures the parallax: no noise on it


#: Noise along a null direction of N (one to three transits) is rounding: at most this many
#: times eps cond(A) of the largest singular value of the star's rows (A: the position block,
#: through whose inverse the noise is carried; measured: up to 25).
NULL_NOISE_ROUNDINGS = 200.0


@pytest.mark.parametrize("blocks", [1, 2])
@pytest.mark.parametrize("k", [1, 2, 3])
def test_no_noise_along_a_null_direction_of_the_star(k, blocks):
    """The noise lies in the range of each star's design rows (independently: their SVD), for
    many random designs and weights, to the rounding of its construction."""
    eps = np.finfo(float).eps
    worst = 0.0
    for seed in range(20):
        rng = np.random.default_rng(1000 * k + 10 * blocks + seed)
        a = _design(rng, k)[:blocks * k]
        n = 100
        weights = [rng.uniform(0.5, 5.0, n), rng.uniform(0.1, 1.0, n)][:blocks]
        n0, b0 = SharedDesignNormals.simulate(a, weights, np.zeros((3, n)), rng).matrices()
        for i in range(n):
            rows = np.concatenate([a[j * k:(j + 1) * k] * weights[j][i] for j in range(blocks)])
            sv, vt = np.linalg.svd(rows)[1:]
            null = vt[np.sum(sv > 1e-12 * sv[0]):]
            if null.size and np.linalg.cond(n0[i, :2, :2]) < 1e12:
                bound = eps * np.linalg.cond(n0[i, :2, :2]) * sv[0]
                worst = max(worst, np.abs(null @ b0[i]).max() / bound)
    assert worst <= NULL_NOISE_ROUNDINGS


def test_more_than_two_blocks_are_refused():
    with pytest.raises(ValueError, match="3 blocks of weights"):
        SharedDesignNormals.simulate(np.zeros((6, 5)), [np.ones(3)] * 3, np.zeros((3, 3)), np.random.default_rng(0))
