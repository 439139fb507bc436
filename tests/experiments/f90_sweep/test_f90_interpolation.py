"""sigma_F90 = the smallest prior whose fraction inside reaches P (paper Sect. 3.3)."""

import math

import numpy as np
import pytest

from mcsweep.experiments.f90_curve import sigma_f90_from_curve

GRID = np.geomspace(0.01, 1000, 41)


def test_log_interpolation_closed_form():
    # Fraction rising linearly in log10(sigma): f = 0.5 + 0.1 log10(sigma / 0.1) crosses
    # 0.9 exactly at sigma = 0.1 * 10**4 = 1000 ... use a steeper curve crossing mid-grid:
    frac = np.clip(0.5 + 0.2 * np.log10(GRID / 0.1), 0, 1)  # crosses 0.9 at sigma = 10**1 = 10 mas
    s, flag = sigma_f90_from_curve(GRID, frac, 0.9, "log")
    assert flag == "ok"
    assert s == pytest.approx(10.0, rel=1e-9)
    # A crossing between grid points (P = 0.87 -> log10(s/0.1) = 1.85 -> s = 7.0795 mas).
    s, _ = sigma_f90_from_curve(GRID, frac, 0.87, "log")
    assert s == pytest.approx(0.1 * 10**1.85, rel=1e-9)
    s, _ = sigma_f90_from_curve(GRID, frac, 0.87, "none")
    assert s == pytest.approx(GRID[np.flatnonzero(frac >= 0.87)[0]])


def test_smallest_crossing_wins_and_flags():
    frac = np.where(GRID < 1, 0.5, 0.95)
    frac[-3:] = 0.85  # falls below P again for very loose priors: the first crossing counts
    s, flag = sigma_f90_from_curve(GRID, frac, 0.9)
    assert flag == "ok" and GRID[15] < s <= 1.0 + 1e-12
    s, flag = sigma_f90_from_curve(GRID, np.full(41, 0.2), 0.9)
    assert flag == "never_reached" and math.isnan(s)
    s, flag = sigma_f90_from_curve(GRID, np.full(41, 0.95), 0.9)
    assert flag == "below_grid" and s == GRID[0]


def test_bootstrap_fractions_have_the_resampling_covariance():
    # Resampling n stars with replacement: the fractions at priors j, l have mean p_j and
    # covariance (p_jl - p_j p_l) / n, p_jl the fraction inside at both (a closed form of
    # the star-by-star bootstrap, independent of the pattern/multinomial shortcut).
    from mcsweep.experiments.f90_curve import bootstrap_fractions

    rng = np.random.default_rng(3)
    n, m, r = 500, 6, 20000
    score = rng.normal(size=n)
    inside = score[None, :] < np.linspace(-1, 1.5, m)[:, None]  # nested, like a real curve
    inside[:, :40] ^= rng.random((m, 40)) < 0.3  # and some non-monotone stars
    valid = np.ones_like(inside)
    frac = bootstrap_fractions(inside, valid, r, np.random.default_rng(8))
    p = inside.mean(axis=1)
    cov = (inside.astype(float) @ inside.T.astype(float) / n - np.outer(p, p)) / n
    # 4 sigma of the Monte Carlo estimate of a mean from r resamples, and of a covariance
    # (its relative standard error is about sqrt(2 / r)).
    assert np.all(np.abs(frac.mean(axis=0) - p) <= 4 * np.sqrt(cov.diagonal() / r))
    np.testing.assert_allclose(np.cov(frac.T), cov, atol=4 * np.sqrt(2.0 / r) * cov.diagonal().max())


def test_bootstrap_fractions_leave_invalid_stars_out():
    from mcsweep.experiments.f90_curve import bootstrap_fractions

    # Star 3 has no confidence region (inside implies valid): it never enters a fraction,
    # so every resample's fraction is one of 0, 1/2, 1 (two valid stars, one inside) ...
    inside = np.array([[True, False, False]])
    valid = np.array([[True, True, False]])
    frac = bootstrap_fractions(inside, valid, 400, np.random.default_rng(1))
    ok = np.isfinite(frac)
    assert set(np.round(frac[ok] * 3 * 2) / 6).issubset({0.0, 1 / 3, 0.5, 2 / 3, 1.0})
    # ... and a resample of only star 3 has no fraction at all (NaN), never 0.
    only3 = bootstrap_fractions(inside[:, 2:], valid[:, 2:], 5, np.random.default_rng(1))
    assert np.isnan(only3).all()


def test_vectorised_crossings_follow_the_one_curve_rule():
    from mcsweep.experiments.f90_curve import prior_crossings

    rng = np.random.default_rng(5)
    curves = np.clip(0.5 + 0.2 * np.log10(GRID / 0.1) + rng.normal(0, 0.05, (300, 41)), 0, 1)
    curves[:20] = 0.95  # below the grid
    curves[20:40] = 0.5  # never reached
    curves[40, 5] = np.nan
    for interp in ("log", "none"):
        values, _ = prior_crossings(GRID, curves, 0.9, interp)
        np.testing.assert_allclose(values, [_one_crossing(c, 0.9, interp) for c in curves], rtol=1e-12)


def _one_crossing(frac, p, interp):
    # Sect. 3.3 written out point by point: the first grid point reaching p, the value
    # interpolated linearly in log(sigma) from the point before.
    for i, f in enumerate(frac):
        if f >= p:
            if i == 0 or interp == "none":
                return GRID[i]
            f0 = frac[i - 1]
            w = (p - f0) / (f - f0) if f > f0 else 1.0
            return 10 ** ((1 - w) * math.log10(GRID[i - 1]) + w * math.log10(GRID[i]))
    return float("nan")


def test_bootstrap_interval_does_not_depend_on_the_order_of_the_stars():
    # Seeded from the cell alone (SeedSequence(seed, spawn_key=(*key, 2))): the same stars in
    # another order must give the same interval, bit for bit (patterns are sorted by content,
    # not by position).
    from mcsweep.experiments.f90_curve import sigma_f90_interval

    rng = np.random.default_rng(11)
    score = rng.normal(size=3000)
    inside = score[None, :] < np.linspace(-2, 2, 41)[:, None]
    valid = np.ones_like(inside)
    perm = rng.permutation(3000)
    a = sigma_f90_interval(GRID, inside, valid, 0.9, "log", 200, np.random.default_rng(5))
    b = sigma_f90_interval(GRID, inside[:, perm], valid[:, perm], 0.9, "log", 200, np.random.default_rng(5))
    assert a == b
    assert a[0] < a[1]


def test_patterns_from_integer_keys_are_the_patterns_of_the_flags():
    from mcsweep.experiments.f90_curve import flag_patterns, key_patterns

    rng = np.random.default_rng(12)
    score = rng.normal(size=5000)
    inside = (score[None, :] < np.linspace(-2, 2, 41)[:, None]) & (rng.random((41, 5000)) < 0.97)
    valid = rng.random((41, 5000)) < 0.99
    inside &= valid
    bits = np.uint64(1) << np.arange(41, dtype=np.uint64)
    k_in = (inside.astype(np.uint64) * bits[:, None]).sum(axis=0, dtype=np.uint64)
    k_val = (valid.astype(np.uint64) * bits[:, None]).sum(axis=0, dtype=np.uint64)
    assert key_patterns(k_in, k_val, 41) == flag_patterns(inside, valid)
    assert key_patterns(k_in[:0], k_val[:0], 41) == {} == flag_patterns(inside[:, :0], valid[:, :0])
