"""Beyond the paper: the smallest factor k for which k sigma_F90 works in the primary solution.

Sect. 4.2 finds that sigma_F90 constrains the one-year global solution too much and that
10 sigma_F90 "provides the necessary relaxation"; it does not say how much relaxation is
needed. Here the factor is searched exactly as sigma_F90 itself is (Sect. 3.3,
:func:`~mcsweep.experiments.pencil_beam.sigma_f90_from_curve`): one global solution per
factor k of a grid (the prior ``k sigma_F90``, Eq. 18 with R sigma), the fraction of actual
position errors inside the P ellipse as a function of k for every cell (G class x subset
<= 4 / > 4 transits), and the smallest k at which the curve reaches P (linear in log k
between the bracketing grid points). Its interval is the bootstrap over the cell's stars
of :func:`~mcsweep.experiments.pencil_beam.sigma_f90_interval` (one resample serves every
k, so the curve keeps its correlation). The factor for the whole solution is the
largest cell value: the smallest k that keeps P inside in every cell.

Every k costs one global solution, so the grid is coarse (a few values); a crossing is
only as good as the grid around it, and the flags say when it falls outside.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ..astrometry.confidence import binomial_interval
from .pencil_beam import sigma_f90_from_curve, sigma_f90_interval
from .secondary_table import FRACTION_INTERVAL, SUBSETS, g_label, subset_masks

__all__ = ["FACTOR_COLUMNS", "CURVE_COLUMNS", "factor_label", "factor_curves", "factor_rows", "overall_factor"]

FACTOR_COLUMNS = ("subset", "g_class", "n_valid", "k_min", "flag", "k_lo", "k_hi")
CURVE_COLUMNS = ("subset", "g_class", "k", "n_valid", "n_inside", "fraction_inside", "fraction_lo", "fraction_hi")


def factor_label(k: float) -> str:
    """The ``priors`` entry of factor ``k`` (``'3F90'``; ``'F90'`` for 1), so solutions are shared with Table 3's."""
    return "F90" if float(k) == 1.0 else f"{float(k):g}F90"


def _flags(results: Mapping[float, pd.DataFrame], subset: str, g: float) -> tuple[np.ndarray, np.ndarray]:
    """(inside, valid) flags (n_k, n_stars) of one cell; the stars are the same in every solution."""
    first = next(iter(results.values()))
    sel = subset_masks(first["n_fov"].to_numpy())[subset] & (first["class_key"].to_numpy() == int(round(100 * g)))
    inside = np.stack([res["inside"].to_numpy()[sel] for res in results.values()])
    return (inside == 1), (inside >= 0)


def factor_curves(results: Mapping[float, pd.DataFrame], g_classes: Sequence[float]) -> pd.DataFrame:
    """Fraction inside per cell and factor, with its Clopper-Pearson interval (as Table 2)."""
    ks = sorted(results)
    res = {k: results[k] for k in ks}
    rows = []
    for subset in SUBSETS:
        for g in g_classes:
            inside, valid = _flags(res, subset, g)
            for i, k in enumerate(ks):
                n_in, n_val = int(inside[i].sum()), int(valid[i].sum())
                lo, hi = binomial_interval(n_in, n_val, FRACTION_INTERVAL)
                rows.append((subset, g_label(g), k, n_val, n_in, n_in / n_val if n_val else float("nan"),
                             float(lo), float(hi)))
    return pd.DataFrame(rows, columns=list(CURVE_COLUMNS))


def factor_rows(results: Mapping[float, pd.DataFrame], g_classes: Sequence[float], confidence: float, *,
                n_resamples: int, rng: np.random.Generator) -> pd.DataFrame:
    """Smallest k per cell (module notes) with flag and bootstrap interval.

    Parameters
    ----------
    results : mapping of factor k -> per-star results of that solution
        (:func:`mcsweep.experiments.primary.solve_prior`, prior ``k sigma_F90``).
    g_classes : the magnitude classes.
    confidence : P.
    n_resamples : bootstrap resamples (0: no interval).
    rng : generator of the bootstrap.
    """
    ks = np.array(sorted(results), dtype=float)
    res = {k: results[k] for k in ks}
    rows = []
    for subset in SUBSETS:
        for g in g_classes:
            inside, valid = _flags(res, subset, g)
            n_val = valid.sum(axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                frac = np.where(n_val > 0, inside.sum(axis=1) / n_val, np.nan)
            if not n_val.any():
                rows.append((subset, g_label(g), 0, float("nan"), "no_stars", float("nan"), float("nan")))
                continue
            k_min, flag = sigma_f90_from_curve(ks, frac, confidence)
            lo, hi = sigma_f90_interval(ks, inside, valid, confidence, "log", n_resamples, rng)
            rows.append((subset, g_label(g), int(n_val.max()), k_min, flag, lo, hi))
    return pd.DataFrame(rows, columns=list(FACTOR_COLUMNS))


def overall_factor(rows: pd.DataFrame) -> tuple[float, str]:
    """(k, flag): the largest cell factor, i.e. the smallest k with P inside in every cell.

    ``'never_reached'`` if some cell never reaches P on the grid (k above the grid).
    """
    have = rows[rows["flag"] != "no_stars"]
    if (have["flag"] == "never_reached").any():
        return float("nan"), "never_reached"
    if have.empty:
        return float("nan"), "no_stars"
    i = int(np.argmax(have["k_min"].to_numpy()))
    return float(have["k_min"].iloc[i]), str(have["flag"].iloc[i])
