"""The factor search of the primary experiment (experiments.primary_factor) against closed forms."""

import numpy as np
import pandas as pd
import pytest

from mcsweep.astrometry.confidence import chi2_threshold
from mcsweep.experiments.primary_factor import factor_curves, factor_label, factor_rows, overall_factor
from mcsweep.experiments.primary import parse_prior

#: Log-linear interpolation between grid points 1.25 apart, on a smooth curve [relative].
RTOL_GRID = 0.02


def _results(ks, true_k, n=20000, seed=3):
    """Per-star results of one cell per class whose formal errors are 1/true_k of the actual ones.

    Actual errors are isotropic 2D Gaussian (sigma 1); the formal covariance of the prior
    k sigma_F90 is (k / true_k)^2 I, so the fraction inside the P ellipse is
    1 - (1 - P)^((k / true_k)^2) (chi-square with 2 dof) and reaches P at k = true_k.
    """
    rng = np.random.default_rng(seed)
    out = {k: [] for k in ks}
    for key, kt in true_k.items():
        r2 = np.sum(rng.standard_normal((n, 2)) ** 2, axis=1)
        n_fov = np.where(np.arange(n) % 10 == 0, 3, 12)  # 10 % in the <= 4 subset
        for k in ks:
            inside = (r2 < (k / kt) ** 2 * chi2_threshold(0.9)).astype(np.int8)
            inside[:5] = -1  # no confidence region: left out
            out[k].append(pd.DataFrame({"class_key": key, "n_fov": n_fov, "inside": inside}))
    return {k: pd.concat(v, ignore_index=True) for k, v in out.items()}


def test_factor_search_finds_the_closed_form_crossing():
    ks = [1.0, 1.25, 1.5625, 1.953125, 2.44140625, 3.0517578125, 3.814697265625]
    true_k = {1100: 2.2, 1500: 1.3}
    res = _results(ks, true_k)
    rows = factor_rows(res, [11.0, 15.0], 0.9, n_resamples=200, rng=np.random.default_rng(0))
    for key, kt in true_k.items():
        for subset in ("<=4", ">4"):
            r = rows[(rows["g_class"] == key // 100) & (rows["subset"] == subset)].iloc[0]
            assert r["flag"] == "ok"
            # The bootstrap interval (68 %) covers the truth up to the grid's interpolation.
            assert r["k_lo"] <= kt * (1 + RTOL_GRID) and kt * (1 - RTOL_GRID) <= r["k_hi"]
        # 18000 stars: binomial noise moves the crossing by ~0.5 %, below the grid's error.
        big = rows[(rows["g_class"] == key // 100) & (rows["subset"] == ">4")].iloc[0]
        assert big["k_min"] == pytest.approx(kt, rel=RTOL_GRID)
    k_all, flag = overall_factor(rows)
    assert flag == "ok" and k_all == pytest.approx(2.2, rel=RTOL_GRID)
    curves = factor_curves(res, [11.0, 15.0])
    c = curves[(curves["subset"] == ">4") & (curves["g_class"] == 11)]
    expected = 1 - 0.1 ** ((np.array(ks) / 2.2) ** 2)
    sigma = np.sqrt(expected * (1 - expected) / c["n_valid"].to_numpy())
    assert np.all(np.abs(c["fraction_inside"].to_numpy() - expected) < 4 * sigma)
    # Star 0 of the five without a region is in the <= 4 subset.
    assert (c["n_valid"] == c["n_valid"].iloc[0]).all() and c["n_valid"].iloc[0] == 18000 - 4


def test_factor_beyond_the_grid_is_flagged():
    ks = [1.0, 2.0]
    rows = factor_rows(_results(ks, {1100: 5.0}), [11.0], 0.9, n_resamples=0, rng=np.random.default_rng(0))
    assert set(rows["flag"]) == {"never_reached"}
    assert overall_factor(rows)[1] == "never_reached"
    rows = factor_rows(_results(ks, {1100: 0.5}), [11.0], 0.9, n_resamples=0, rng=np.random.default_rng(0))
    assert set(rows["flag"]) == {"below_grid"} and (rows["k_min"] == 1.0).all()


def test_factor_label_is_a_prior_of_the_experiment():
    for k in (1, 2.5, 10, 31.6):
        assert parse_prior(factor_label(k)) == ("F90", float(k))
