"""Batched Cholesky solver against LAPACK (numpy.linalg) as the independent reference."""

import numpy as np
import pytest

from mcsweep.astrometry import linalg
from mcsweep.astrometry.linalg import spd_solve

#: Relative agreement with numpy.linalg for well-conditioned matrices (dimensionless).
LAPACK_RTOL = 1e-10


def _random_spd(rng, n, p, m=12):
    A = rng.normal(size=(n, m, p)) * rng.uniform(0.1, 10.0, size=(n, 1, p))  # mixed scales
    return np.einsum("nmi,nmj->nij", A, A)


@pytest.mark.parametrize("p", [2, 5])
def test_matches_numpy_linalg(p):
    rng = np.random.default_rng(1)
    N = _random_spd(rng, 700, p)
    b = rng.normal(size=(700, p))
    x, cov, ok, cond = spd_solve(N, b, with_condition=True)
    assert ok.all()
    np.testing.assert_allclose(x, np.linalg.solve(N, b[..., None])[..., 0], rtol=LAPACK_RTOL)
    np.testing.assert_allclose(cov, np.linalg.inv(N), rtol=LAPACK_RTOL)
    # 1-norm condition number of the unit-diagonal matrix, computed by numpy.
    d = np.sqrt(np.einsum("nii->ni", N))
    S = N / d[:, :, None] / d[:, None, :]
    np.testing.assert_allclose(cond, np.linalg.cond(S, 1), rtol=1e-8)


def test_blocks_do_not_change_results(monkeypatch):
    rng = np.random.default_rng(2)
    N = _random_spd(rng, 1000, 5)
    b = rng.normal(size=(1000, 5))
    x1, c1, _, _ = spd_solve(N, b)
    monkeypatch.setattr(linalg, "BLOCK_SIZE", 97)
    x2, c2, _, _ = spd_solve(N, b)
    np.testing.assert_array_equal(x1, x2)
    np.testing.assert_array_equal(c1, c2)


def test_diagonal_addition_equals_explicit_sum():
    rng = np.random.default_rng(3)
    N = _random_spd(rng, 50, 5)
    b = rng.normal(size=(50, 5))
    add = rng.uniform(0, 3, size=(50, 5))
    x, cov, ok, _ = spd_solve(N, b, add_diagonal=add)
    N_sum = N + np.einsum("ni,ij->nij", add, np.eye(5))
    np.testing.assert_allclose(x, np.linalg.solve(N_sum, b[..., None])[..., 0], rtol=LAPACK_RTOL)
    np.testing.assert_allclose(cov, np.linalg.inv(N_sum), rtol=LAPACK_RTOL)
    N_before = N.copy()
    spd_solve(N, b, add_diagonal=add[0])
    np.testing.assert_array_equal(N, N_before)  # inputs are not modified


def test_singular_and_non_finite_matrices_are_flagged_individually():
    rng = np.random.default_rng(4)
    N = _random_spd(rng, 6, 5)
    b = rng.normal(size=(6, 5))
    v = rng.normal(size=(3, 5))
    N[1] = v.T @ v  # rank 3
    N[3, 2, 4] = N[3, 4, 2] = np.nan
    b[4, 0] = np.inf
    N[5, 3, 3] = 0.0  # zero diagonal
    x, cov, ok, cond = spd_solve(N, b, with_condition=True)
    np.testing.assert_array_equal(ok, [True, False, True, False, False, False])
    assert np.all(np.isnan(x[~ok])) and np.all(np.isnan(cov[~ok]))
    assert np.all(np.isinf(cond[~ok]))
    np.testing.assert_allclose(x[ok], np.linalg.solve(N[ok], b[ok][..., None])[..., 0], rtol=LAPACK_RTOL)
