"""The factor search of the primary experiment (experiments.primary_factor) against closed forms."""

import numpy as np
import pandas as pd
import pytest

from mcsweep.astrometry.confidence import chi2_threshold
from mcsweep.experiments.primary.factor import factor_curves, factor_label, factor_rows, overall_factor
from mcsweep.experiments.global_solution.priors import parse_prior
from mcsweep.experiments.primary.table import table3_rows

#: Log-linear interpolation between grid points 1.25 apart, on a smooth curve [relative].
RTOL_GRID = 0.02
#: Two implementations of the same exact interval (beta quantiles vs. scipy's binomtest).
RTOL_INTERVAL = 1e-9


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


def test_factor_curves_and_table3_count_the_same_cells():
    # Hand-built per-star results of two solutions (k = 2 given before k = 1): classes
    # G ~ 11 and 15, extra primary sources (class key 0: in no cell), stars with no FoV
    # transit (in no subset) and stars without a confidence region (-1: out of n_valid).
    # The reference counts come from a plain loop over the stars, not from the code.
    from scipy import stats
    rng = np.random.default_rng(17)
    n = 3000
    frame = pd.DataFrame({"class_key": rng.choice([0, 1100, 1500], n), "n_fov": rng.integers(0, 12, n),
                          "err_mas": rng.rayleigh(size=n)})
    results = {k: frame.assign(inside=rng.choice([-1, 0, 1], n, p=[0.05, 0.35, 0.6]).astype(np.int8))
               for k in (2.0, 1.0)}
    curves = factor_curves(results, [11.0, 15.0])
    table = table3_rows({"F90": results[1.0]}, [11.0, 15.0], 0.9)
    for subset in ("<=4", ">4"):
        for g in (11, 15):
            for k, res in results.items():
                n_in = n_valid = 0
                for key, nf, flag in zip(res["class_key"], res["n_fov"], res["inside"]):
                    if key == 100 * g and nf >= 1 and (nf <= 4) == (subset == "<=4"):
                        n_valid += flag >= 0
                        n_in += flag == 1
                c = curves[(curves["subset"] == subset) & (curves["g_class"] == g) & (curves["k"] == k)]
                assert len(c) == 1 and (c["n_valid"].iloc[0], c["n_inside"].iloc[0]) == (n_valid, n_in)
                assert c["fraction_inside"].iloc[0] == n_in / n_valid  # exact: the same two integers divided
                ci = stats.binomtest(n_in, n_valid).proportion_ci(0.68, method="exact")
                np.testing.assert_allclose(c[["fraction_lo", "fraction_hi"]].to_numpy()[0], [ci.low, ci.high],
                                           rtol=RTOL_INTERVAL)
                if k == 1.0:  # Table 3's row of the same solution: the same cell statistics
                    t = table[(table["subset"] == subset) & (table["g_class"] == g)]
                    cols = ["n_valid", "n_inside", "fraction_inside", "fraction_lo", "fraction_hi"]
                    assert t[cols].to_numpy().tolist() == c[cols].to_numpy().tolist()
