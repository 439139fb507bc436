"""The experiment's tables: per unit x k x prior x class of stars, and per source.

Classes of stars. A zero-centred Gaussian prior of width sigma_F90 on the parallax and
sigma_mu = R sigma_F90 on each proper-motion component (Eq. 18) cannot hold a star whose
true parallax or proper motion lies far out in its tails: its position is then biased by
more than the posterior covariance admits (Sect. 2.4: a Gaussian prior says 90 % of
parallaxes are below 1.28 sigma, 99 % below 2.33 sigma). A source is *not held* when, by
its truth, |parallax| > :data:`HOLD_LIMIT_SIGMA` sigma_F90 or |mu| > :data:`HOLD_LIMIT_SIGMA`
sigma_mu (the paper's sigma_F90 at its l, b, G; R of the run), else *held*; a source
without a truth is in neither.

Cells. For one unit, k, prior and class: the fraction of subsets whose truth lies inside
the P ellipse, of those with an ellipse, with its Clopper-Pearson interval
(:data:`~mcsweep.experiments.global_solution.table.FRACTION_INTERVAL`, treating the draws as
independent), and the 100 P-th percentile of |position error| [mas]; both also with a
bootstrap interval over the sources (``bootstrap`` resamples of the class's sources with
replacement, each taking all its draws): the draws of one source share its truth and
geometry, so the sources, not the draws, are the independent units. One resampling per
(unit, k, class), ``SeedSequence(seed, spawn_key=(TAG, BOOTSTRAP_STREAM, unit index, k,
class index))``, shared by the priors so that their intervals are paired.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...astrometry.confidence import binomial_interval
from ..global_solution.table import FRACTION_INTERVAL, error_percentile, fraction_from_counts
from ...astrometry.design import JULIAN_YEAR_DAYS
from .solutions import POSITION_ONLY, TRUTH_EPOCH_JD, Truth
from .subsets import BOOTSTRAP_STREAM, TAG, UNITS

__all__ = ["HOLD_LIMIT_SIGMA", "CLASSES", "NO_TRUTH", "INTERVAL_QUANTILES", "star_classes",
           "transit_unit_weight_variance", "pooled_percentiles", "cell_rows", "source_rows", "prior_order"]

#: A star is not held by the prior beyond this many prior sigmas (module notes): a Gaussian
#: gives |parallax| > 3 sigma a probability of 0.27 % and |mu| > 3 sigma_mu (two components,
#: Rayleigh) exp(-4.5) = 1.1 %, so such a star lies where the prior says stars are not.
HOLD_LIMIT_SIGMA = 3.0
#: The classes of the table; ``all`` is held and not held together.
CLASSES = ("held", "not_held", "all")
#: The class of a source without a truth (not in ``all``).
NO_TRUTH = "no_truth"
#: Quantiles of a bootstrap interval: central, of probability FRACTION_INTERVAL (16-84 %).
INTERVAL_QUANTILES = (0.5 - FRACTION_INTERVAL / 2, 0.5 + FRACTION_INTERVAL / 2)
#: Bootstrap values held at once (resamples x pooled errors): ~32 MB of float64.
_BOOT_ELEMENTS = 4_000_000


def star_classes(truth: Truth, sigma_f90_mas: np.ndarray, ratio_R: float) -> np.ndarray:
    """'held', 'not_held' or 'no_truth' per source (module notes)."""
    plx = np.abs(truth.x[:, 2])
    pm = np.hypot(truth.x[:, 3], truth.x[:, 4])
    held = (plx <= HOLD_LIMIT_SIGMA * sigma_f90_mas) & (pm <= HOLD_LIMIT_SIGMA * ratio_R * sigma_f90_mas)
    return np.where(~truth.ok, NO_TRUTH, np.where(held, "held", "not_held"))


def transit_unit_weight_variance(obs, truth: Truth) -> np.ndarray:
    """Per source: the mean over its FoV transits of z^2, z = the weighted mean residual of the
    transit's CCDs from the truth over its formal error.

    With independent CCD errors of the stated sizes (sigma and the excess noise in
    quadrature, :mod:`mcsweep.astrometry.source_update`), z has unit variance and this is
    ~1 ((n - 5) / n with n transits); errors shared by a transit's CCDs (attitude,
    calibration, a source model's error per transit) make it larger, and a solution from a
    few transits then has actual errors larger than its formal ones by about its square root.
    """
    s = np.searchsorted(truth.source_id, obs.source_id)
    x = truth.x[s]
    t_yr = (obs.tcb_jd - TRUTH_EPOCH_JD) / JULIAN_YEAR_DAYS
    th = np.deg2rad(obs.scan_angle_deg)
    model = (np.sin(th) * (x[:, 0] + t_yr * x[:, 3]) + np.cos(th) * (x[:, 1] + t_yr * x[:, 4])
             + obs.parallax_factor_al * x[:, 2])
    w = 1.0 / (obs.sigma_al_mas ** 2 + obs.excess_noise_mas ** 2)
    tid, tpos = np.unique(obs.transit, return_inverse=True)
    sum_w = np.bincount(tpos, w)
    mean_res = np.bincount(tpos, w * (obs.centroid_al_mas - model)) / sum_w
    z2 = mean_res ** 2 * sum_w
    src_of_transit = np.zeros(tid.size, np.int64)
    src_of_transit[tpos] = s
    n = np.bincount(src_of_transit, minlength=truth.source_id.size)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.bincount(src_of_transit, z2, minlength=truth.source_id.size) / n
    return np.where(truth.ok, out, np.nan)


def pooled_percentiles(values: np.ndarray, owner: np.ndarray, weights: np.ndarray, q: float) -> np.ndarray:
    """The q-th percentile of the pooled values of each resample, linear interpolation as
    :func:`numpy.percentile`; (B,), NaN for a resample without values.

    ``values`` (m,) belong to sources ``owner`` (m,); a resample takes source ``s``
    ``weights[b, s]`` times. Without forming the pooled samples: the values sorted once,
    each resample's cumulative multiplicities give the ranks.
    """
    order = np.argsort(values, kind="stable")
    v, o = values[order], owner[order]
    out = np.full(weights.shape[0], np.nan)
    if v.size == 0:
        return out
    step = max(1, _BOOT_ELEMENTS // v.size)
    for lo in range(0, weights.shape[0], step):
        c = np.cumsum(weights[lo:lo + step][:, o], axis=1)
        n = c[:, -1]
        h = q / 100.0 * (n - 1)
        i0 = np.floor(h)
        i1 = np.minimum(i0 + 1, n - 1)
        j0 = np.minimum((c <= i0[:, None]).sum(axis=1), v.size - 1)
        j1 = np.minimum((c <= i1[:, None]).sum(axis=1), v.size - 1)
        val = v[j0] + (h - i0) * (v[j1] - v[j0])
        out[lo:lo + step] = np.where(n > 0, val, np.nan)
    return out


def _bootstrap_weights(seed: int, unit: str, k: int, cls: str, n_sources: int, n_boot: int) -> np.ndarray:
    """(n_boot, n_sources) counts of each source in each resample (module notes)."""
    ss = np.random.SeedSequence(int(seed), spawn_key=(TAG, BOOTSTRAP_STREAM, UNITS.index(unit), int(k),
                                                      CLASSES.index(cls)))
    idx = np.random.default_rng(ss).integers(0, n_sources, size=(n_boot, n_sources))
    flat = (np.arange(n_boot)[:, None] * n_sources + idx).ravel()
    return np.bincount(flat, minlength=n_boot * n_sources).reshape(n_boot, n_sources)


def _interval(samples: np.ndarray) -> tuple[float, float]:
    s = samples[np.isfinite(samples)]
    if s.size == 0:
        return float("nan"), float("nan")
    lo, hi = np.quantile(s, INTERVAL_QUANTILES)
    return float(lo), float(hi)


def cell_rows(results: pd.DataFrame, classes: dict, priors: tuple, sizes: dict, *, seed: int, confidence: float,
              n_boot: int) -> pd.DataFrame:
    """``real_epochs.csv`` (module notes): one row per unit x k x prior x class.

    ``results``: the subsets' rows (:func:`~.solutions.solve_chunk`); ``classes``: source_id
    -> class; ``priors``: the prior names, ``'none'`` (position only) last.
    """
    q = error_percentile(confidence)
    cls_of_row = results["source_id"].map(classes).to_numpy() if len(results) else np.empty(0, object)
    rows = []
    for unit in UNITS:
        for k in sizes.get(unit, ()):
            in_cell = ((results["unit"] == unit) & (results["k"] == k)).to_numpy()
            for cls in CLASSES:
                m = in_cell & (np.isin(cls_of_row, ("held", "not_held")) if cls == "all" else cls_of_row == cls)
                part = results[m]
                ids, owner = np.unique(part["source_id"].to_numpy(), return_inverse=True)
                weights = _bootstrap_weights(seed, unit, k, cls, ids.size, n_boot) if ids.size else None
                n_tr = part["n_transits"].to_numpy()
                for prior in priors:
                    flags = part[f"inside_{prior}"].to_numpy()
                    err = part[f"err_{prior}_mas"].to_numpy(np.float64)
                    valid, inside = flags >= 0, flags == 1
                    n_valid, n_in = int(valid.sum()), int(inside.sum())
                    frac, lo, hi = fraction_from_counts(n_in, n_valid)
                    row = {"unit": unit, "k": k, "prior": prior, "star_class": cls, "n_sources": int(ids.size),
                           "n_draws": int(m.sum()), "n_valid": n_valid, "n_inside": n_in, "fraction_inside": frac,
                           "fraction_lo": lo, "fraction_hi": hi, "fraction_boot_lo": np.nan,
                           "fraction_boot_hi": np.nan,
                           "p_error_mas": float(np.percentile(err[valid], q)) if n_valid else np.nan,
                           "p_error_boot_lo_mas": np.nan, "p_error_boot_hi_mas": np.nan,
                           "median_n_transits": float(np.median(n_tr)) if n_tr.size else np.nan}
                    if weights is not None and n_valid:
                        per_in = np.bincount(owner, inside, minlength=ids.size)
                        per_valid = np.bincount(owner, valid, minlength=ids.size)
                        with np.errstate(invalid="ignore", divide="ignore"):
                            boot_frac = (weights @ per_in) / (weights @ per_valid)
                        row["fraction_boot_lo"], row["fraction_boot_hi"] = _interval(boot_frac)
                        boot_err = pooled_percentiles(err[valid], owner[valid], weights, q)
                        row["p_error_boot_lo_mas"], row["p_error_boot_hi_mas"] = _interval(boot_err)
                    rows.append(row)
    return pd.DataFrame(rows)


def source_rows(results: pd.DataFrame, sources: pd.DataFrame, priors: tuple, sizes: dict, *,
                confidence: float) -> pd.DataFrame:
    """``real_epochs_sources.csv``: one row per source x unit x k x prior, the source's
    columns (``sources``, one row per source) first, then its subsets' fraction inside
    [Clopper-Pearson interval] and 100 P-th percentile error (no row of draws: n_draws 0)."""
    q = error_percentile(confidence)
    keys = pd.MultiIndex.from_tuples([(u, k) for u in UNITS for k in sizes.get(u, ())], names=["unit", "k"])
    grid = sources.merge(pd.DataFrame(index=keys).reset_index(), how="cross").merge(
        pd.DataFrame({"prior": list(priors)}), how="cross")
    stats = []
    if len(results):
        g = results.groupby(["source_id", "unit", "k"], sort=False)
        for prior in priors:
            f = results[f"inside_{prior}"]
            e = results[f"err_{prior}_mas"].astype(np.float64)
            s = pd.DataFrame({"n_draws": g.size(), "n_valid": (f >= 0).groupby([results["source_id"], results["unit"],
                                                                                 results["k"]]).sum(),
                              "n_inside": (f == 1).groupby([results["source_id"], results["unit"], results["k"]]).sum(),
                              "p_error_mas": e.groupby([results["source_id"], results["unit"], results["k"]]).quantile(
                                  q / 100.0)})
            stats.append(s.reset_index().assign(prior=prior))
    cols = ["source_id", "unit", "k", "prior", "n_draws", "n_valid", "n_inside", "p_error_mas"]
    stats = pd.concat(stats, ignore_index=True)[cols] if stats else pd.DataFrame(columns=cols)
    out = grid.merge(stats, on=["source_id", "unit", "k", "prior"], how="left")
    for c in ("n_draws", "n_valid", "n_inside"):
        out[c] = out[c].fillna(0).astype(np.int64)
    lo, hi = binomial_interval(out["n_inside"].to_numpy(), out["n_valid"].to_numpy(), FRACTION_INTERVAL)
    with np.errstate(invalid="ignore", divide="ignore"):
        out["fraction_inside"] = np.where(out["n_valid"] > 0, out["n_inside"] / out["n_valid"], np.nan)
    out["fraction_lo"], out["fraction_hi"] = lo, hi
    return out[list(sources.columns) + ["unit", "k", "prior", "n_draws", "n_valid", "n_inside", "fraction_inside",
                                        "fraction_lo", "fraction_hi", "p_error_mas"]]


def prior_order(priors) -> tuple:
    """The table's prior names: the configured ones, 'fitted' if any, 'none' last."""
    return tuple(p for p in priors if p != POSITION_ONLY) + (POSITION_ONLY,)
