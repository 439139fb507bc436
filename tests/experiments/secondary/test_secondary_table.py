"""Table 2's counts: integers from the per-star flags, never rebuilt from a fraction.

Review finding: ``table2_rows`` rebuilt the number inside as ``round(fraction * n_valid)``
for the Clopper-Pearson interval. With a float64 fraction that round trip is exact for
any n_valid < 2**51 (the error of n/d*d is below n 2**-52), so the old code gave the right
interval; a float32 fraction (relative error up to 2**-24) loses it from about 8.4e6
stars inside (first failing cell found here: 8477896 of 16777310). Now the counts are
carried from the flags, whose rule is that of ``astrometry.confidence.inside_counts``.
"""

import numpy as np
import pandas as pd
from scipy import stats

from mcsweep.astrometry.confidence import binomial_interval, inside, inside_counts, mahalanobis_sq
from mcsweep.experiments.global_solution.table import fraction_statistics
from mcsweep.experiments.secondary.table import SOLUTION_COLUMNS, no_prior_rows, table2_rows

#: Two implementations of the same exact interval (beta quantiles vs. scipy's binomtest).
RTOL_INTERVAL = 1e-9
P = 0.9


def _cell(n, rng):
    """Position errors and covariances of ``n`` stars, a tenth of them without a region (NaN)."""
    dpos = rng.standard_normal((n, 2))
    scale = rng.uniform(0.5, 2.0, n)  # formal errors from half to twice the actual ones
    cov2 = np.einsum("i,jk->ijk", scale ** 2, np.eye(2))
    cov2[::10] = np.nan
    return dpos, cov2


def _flags(dpos, cov2):
    """Per-star flags as the per-star results store them: 1 inside, 0 outside, -1 no region."""
    flags = np.where(inside(dpos, cov2, P), 1, 0).astype(np.int8)
    flags[~np.isfinite(mahalanobis_sq(dpos, cov2))] = -1
    return flags


def test_table2_fraction_and_interval_from_inside_counts():
    # One class, 300 stars with <= 4 and 700 with > 4 transits, plus 50 never observed
    # (n_fov 0: in no subset); every solution column holds the same cell.
    rng = np.random.default_rng(7)
    n_fov = np.r_[np.full(300, 3), np.full(700, 9), np.zeros(50, int)]
    dpos, cov2 = _cell(n_fov.size, rng)
    d = {"n_fov": n_fov}
    for col in SOLUTION_COLUMNS.values():
        d[f"inside_{col}"] = _flags(dpos, cov2)
        d[f"err_{col}_mas"] = np.hypot(dpos[:, 0], dpos[:, 1]).astype(np.float32)
    t = table2_rows([(15.0, pd.DataFrame(d))], P)
    no_prior = no_prior_rows([(15.0, pd.DataFrame(d))], P)
    for subset, sel in (("<=4", slice(0, 300)), (">4", slice(300, 1000))):
        n_in, n_valid = inside_counts(dpos[sel], cov2[sel], P)
        n_stars = sel.stop - sel.start
        assert n_valid == n_stars * 9 // 10  # the NaN rule took one in ten out
        rows = t[t["subset"] == subset]
        assert len(rows) == 5 and (rows["n_stars"] == n_stars).all()
        # Exact: the same two integers divided.
        assert (rows["fraction_inside"] == n_in / n_valid).all()
        ci = stats.binomtest(n_in, n_valid).proportion_ci(0.68, method="exact")
        np.testing.assert_allclose(rows["fraction_lo"], ci.low, rtol=RTOL_INTERVAL)
        np.testing.assert_allclose(rows["fraction_hi"], ci.high, rtol=RTOL_INTERVAL)
        r = no_prior[no_prior["subset"] == subset].iloc[0]
        assert r["n_unsolved"] == r["n_stars"] - n_valid and r["fraction_inside"] == n_in / n_valid


def test_fraction_statistics_counts_are_exact_where_a_float32_fraction_is_not():
    n_valid, n_in = 16_777_310, 8_477_896
    frac32 = np.float32(n_in / n_valid)
    # The premise: the round trip through a float32 fraction, in float32 or in float64, misses by one.
    assert round(frac32 * n_valid) != n_in and round(float(frac32) * n_valid) != n_in
    flags = np.zeros(n_valid + 1000, dtype=np.int8)
    flags[:n_in] = 1
    flags[-1000:] = -1  # no region: out of the denominator
    nv, ni, frac, lo, hi = fraction_statistics(flags)
    assert (nv, ni) == (n_valid, n_in)
    assert frac == n_in / n_valid
    assert (lo, hi) == tuple(float(v) for v in binomial_interval(n_in, n_valid, 0.68))
