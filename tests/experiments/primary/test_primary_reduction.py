"""Table 3's cells reduced part by part (experiments.primary_cells) against numpy's and scipy's
statistics of all the values at once, and against themselves split otherwise (bit identity)."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from mcsweep.astrometry.confidence import percentile_interval
from mcsweep.experiments.global_solution.table import FRACTION_INTERVAL
from mcsweep.experiments.f90_curve import sigma_f90_from_curve
from mcsweep.experiments.primary.reduction import SPAN_QUANTILES, TableReduction, RankSelector, reduce_parts
from mcsweep.experiments.primary.factor import factor_rows, rows_from_reduction
from mcsweep.experiments.primary.table import cell_statistics, table3_from_reduction, table3_rows

#: numpy's percentile and ours from the same two order statistics: the same formula, so
#: equal up to the last bit; a relative 1e-15 allows one rounding of difference.
RTOL_SAME_FORMULA = 1e-15
#: Two implementations of the same exact interval (beta quantiles vs. scipy's binomtest).
RTOL_INTERVAL = 1e-9


def _results(n, seed, labels=("F90", "10F90", "1000mas")):
    rng = np.random.default_rng(seed)
    n_fov = rng.integers(0, 14, n)
    key = rng.choice([1100, 1500, 1900, 0], n)
    span = np.where(n_fov >= 1, rng.exponential(30.0, n), np.nan).astype(np.float32)
    out = {}
    for i, lab in enumerate(labels):
        err = (rng.lognormal(-1.0 + i, 1.0, n)).astype(np.float32)
        inside = np.where(n_fov >= 1, (rng.uniform(size=n) < 0.85 + 0.03 * i).astype(np.int8), -1).astype(np.int8)
        inside[rng.uniform(size=n) < 0.01] = -1
        out[lab] = pd.DataFrame({"class_key": key, "n_fov": n_fov.astype(np.int16), "inside": inside,
                                 "err_mas": err, "span_days": span})
    return out


def test_rank_selector_gives_numpys_order_statistics():
    rng = np.random.default_rng(1)
    # ties, negatives, zeros and non-finite values, split in uneven parts
    x = np.concatenate([rng.normal(0, 3, 5000), np.zeros(40), np.full(30, 2.5), [np.nan, np.inf, -np.inf]])
    x = rng.permutation(x).astype(np.float32)
    parts = np.array_split(x, [7, 1000, 1001, 4000])
    sel = RankSelector()
    for p in parts:
        sel.count(p)
    finite = np.sort(x[np.isfinite(x)])
    assert sel.n == finite.size and sel.n_nonfinite == 3
    ranks = [0, 1, 17, 2500, finite.size - 1]
    sel.want(ranks)
    for p in parts[::-1]:  # pass 2 in any order
        sel.collect(p)
    assert [sel.value(r) for r in ranks] == [float(finite[r]) for r in ranks]


def test_table3_cells_part_by_part_are_numpys_and_scipys_over_all_stars():
    res = _results(20000, 2)
    table = table3_rows(res, [11.0, 15.0, 19.0], 0.9)
    for _, row in table.iterrows():
        r = res[row["prior"]]
        sub = (r["n_fov"] <= 4) & (r["n_fov"] >= 1) if row["subset"] == "<=4" else r["n_fov"] > 4
        m = (sub & (r["class_key"] == 100 * row["g_class"])).to_numpy()
        inside, err = r["inside"].to_numpy()[m], r["err_mas"].to_numpy()[m]
        n_valid, n_in, frac, lo, hi, p, plo, phi = cell_statistics(inside, err, 0.9)
        assert (row["n_stars"], row["n_valid"], row["n_inside"]) == (m.sum(), n_valid, n_in)
        assert row["fraction_inside"] == frac and (row["fraction_lo"], row["fraction_hi"]) == (lo, hi)
        # and independently: the counts by numpy, the Clopper-Pearson interval by scipy's binomtest
        flags = inside[inside >= 0]
        n_v, n_i = int(np.count_nonzero(inside >= 0)), int(np.count_nonzero(flags == 1))
        assert (row["n_valid"], row["n_inside"]) == (n_v, n_i) and row["fraction_inside"] == n_i / n_v
        ci = stats.binomtest(n_i, n_v).proportion_ci(FRACTION_INTERVAL, method="exact")
        np.testing.assert_allclose([row["fraction_lo"], row["fraction_hi"]], [ci.low, ci.high], rtol=RTOL_INTERVAL)
        valid = err[inside >= 0].astype(float)
        assert row["p90_error_mas"] == pytest.approx(np.percentile(valid, 100 * 0.9), rel=RTOL_SAME_FORMULA, abs=0)
        # the rank interval: order statistics, exactly scipy's
        assert (row["p90_error_lo_mas"], row["p90_error_hi_mas"]) == percentile_interval(valid, 90.0,
                                                                                      FRACTION_INTERVAL)


def _split(res, cuts):
    """The solutions' per-star results in parts at the star indices ``cuts``."""
    edges = [0, *cuts, len(next(iter(res.values())))]
    return [{lab: df.iloc[a:b].reset_index(drop=True) for lab, df in res.items()} for a, b in zip(edges, edges[1:])]


def test_tables_do_not_depend_on_the_parts():
    res = _results(30000, 3, labels=("F90", "2F90", "4F90"))
    factors = {1.0: "F90", 2.0: "2F90", 4.0: "4F90"}
    whole = TableReduction(list(res), [11.0, 15.0, 19.0], 0.9, factors=factors)
    reduce_parts(lambda _: res, 1, whole)
    for cuts in ([1, 29999], [7000, 7001, 15000, 22222]):
        parts = _split(res, cuts)
        split = reduce_parts(lambda j: parts[j], len(parts),
                             TableReduction(list(res), [11.0, 15.0, 19.0], 0.9, factors=factors))
        pd.testing.assert_frame_equal(table3_from_reduction(whole, list(res)), table3_from_reduction(split, list(res)),
                                      check_exact=True)
        a = rows_from_reduction(whole, n_resamples=50, rng=np.random.default_rng(4))
        b = rows_from_reduction(split, n_resamples=50, rng=np.random.default_rng(4))
        pd.testing.assert_frame_equal(a, b, check_exact=True)
        for g in (11.0, 15.0, 19.0):
            (qa, fa), (qb, fb) = whole.span_summary(g), split.span_summary(g)
            assert fa == fb and np.array_equal(qa, qb)


def test_few_transit_spans_are_numpys_quantiles():
    res = _results(20000, 5)
    red = reduce_parts(lambda _: res, 1, TableReduction(list(res), [15.0], 0.9))
    r = res["F90"]
    m = ((r["class_key"] == 1500) & (r["n_fov"] >= 1) & (r["n_fov"] <= 4)).to_numpy()
    span = r["span_days"].to_numpy()[m].astype(float)
    q, within = red.span_summary(15.0)
    np.testing.assert_allclose(q, np.nanquantile(span, SPAN_QUANTILES), rtol=RTOL_SAME_FORMULA, atol=0)
    assert within == np.mean(span < 1)


def _bootstrap_interval(ks, flags, n_resamples, rng):
    """The Sect. 3.3 bootstrap of the crossing, written out here: star counts per distinct
    (inside, valid) pattern in the order of the packed patterns' bytes, one multinomial draw
    over them per resample, each resample's crossing (+inf if never reached), the 16-84 %
    quantiles."""
    key = np.packbits(np.concatenate([flags == 1, flags >= 0]), axis=0).T
    patterns, counts = np.unique(key, axis=0, return_counts=True)
    bits = np.unpackbits(patterns, axis=1)[:, :2 * len(ks)].astype(float)
    weights = rng.multinomial(counts.sum(), counts / counts.sum(), size=n_resamples).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = (weights @ bits[:, :len(ks)]) / (weights @ bits[:, len(ks):])
    values = np.array([sigma_f90_from_curve(ks, f, 0.9)[0] for f in frac])
    values[np.isnan(values)] = np.inf
    lo, hi = np.quantile(values, (0.16, 0.84), method="inverted_cdf")
    return float(lo), float(hi)


def test_factor_bootstrap_over_patterns_is_the_bootstrap_over_stars():
    """The interval from the cell's pattern counts equals the bootstrap over its stars'
    flags (the Sect. 3.3 bootstrap, written out in the test), the same draws."""
    res = _results(20000, 6, labels=("F90", "2F90", "4F90"))
    rows = factor_rows({1.0: res["F90"], 2.0: res["2F90"], 4.0: res["4F90"]}, [19.0], 0.9, n_resamples=100,
                       rng=np.random.default_rng(9))
    rng = np.random.default_rng(9)
    for subset in ("<=4", ">4"):
        r = res["F90"]
        sub = ((r["n_fov"] >= 1) & (r["n_fov"] <= 4)) if subset == "<=4" else r["n_fov"] > 4
        m = (sub & (r["class_key"] == 1900)).to_numpy()
        flags = np.stack([res[lab]["inside"].to_numpy()[m] for lab in ("F90", "2F90", "4F90")])
        lo, hi = _bootstrap_interval(np.array([1.0, 2.0, 4.0]), flags, 100, rng)
        row = rows[rows["subset"] == subset].iloc[0]
        assert (row["k_lo"], row["k_hi"]) == (lo, hi)
