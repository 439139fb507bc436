"""Simulated measurements: signal, noise statistics, masking, reproducibility."""

import numpy as np
import pytest
from scipy import stats

from mcsweep.astrometry.design import design_matrix
from mcsweep.astrometry.measurements import simulate
from mcsweep.errors import UserInputError

#: Smallest acceptable KS p-value for the noise distribution test (fixed seed).
KS_MIN_PVALUE = 0.01


def _design(rng, n=300, k=8, mask=None):
    return design_matrix(rng.uniform(0, 360, n), rng.uniform(-80, 80, n), rng.uniform(-1, 1, (n, k)),
                         rng.uniform(0, 360, (n, k)), rng.normal(size=(n, k, 3)),
                         sigma_al_mas=0.3, sigma_ac_mas=2.0, mask=mask)


def test_noise_is_standard_normal_around_the_signal():
    rng = np.random.default_rng(1)
    A = _design(rng)
    x_true = np.column_stack([np.zeros((300, 2)), rng.uniform(0, 3, 300), rng.normal(0, 10, (300, 2))])
    h = simulate(A, x_true, np.random.default_rng(2))
    resid = h - np.einsum("nmj,nj->nm", A, x_true)
    assert stats.kstest(resid.ravel(), "norm").pvalue > KS_MIN_PVALUE
    assert abs(resid.std() - 1.0) < 0.02  # 4800 draws: standard error of the std 0.01


def test_absent_rows_are_zero_with_or_without_mask():
    rng = np.random.default_rng(3)
    mask = rng.uniform(size=(300, 8)) < 0.5
    A = _design(rng, mask=mask)
    x_true = np.array([0.0, 0.0, 1.0, 2.0, 3.0])
    rows = np.concatenate([mask, mask], axis=1)
    for h in (simulate(A, x_true, 5, mask=mask), simulate(A, x_true, 5)):
        np.testing.assert_array_equal(h[~rows], 0.0)
        assert np.all(h[rows] != 0.0)
    np.testing.assert_array_equal(simulate(A, x_true, 5, mask=mask), simulate(A, x_true, 5))


def test_reproducible_from_seed_and_refuses_global_randomness():
    rng = np.random.default_rng(4)
    A = _design(rng, n=10)
    np.testing.assert_array_equal(simulate(A, np.zeros(5), 42), simulate(A, np.zeros(5), np.random.default_rng(42)))
    assert not np.array_equal(simulate(A, np.zeros(5), 42), simulate(A, np.zeros(5), 43))
    with pytest.raises(UserInputError, match="rng"):
        simulate(A, np.zeros(5), None)
