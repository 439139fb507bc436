"""Normal equations of stars sharing one design, in factored form, against the explicit path."""

import numpy as np
import pytest

from mcsweep.astrometry.prior_scan import prior_scan
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
    assert normals.unit.shape == (2, min(k, 5), 5) and normals.noise.shape == (2, min(k, 5), n)
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
