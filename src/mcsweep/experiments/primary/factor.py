"""Beyond the paper: the smallest factor k for which k sigma_F90 works in the primary solution.

Sect. 4.2 finds that sigma_F90 constrains the one-year global solution too much and that
10 sigma_F90 "provides the necessary relaxation"; it does not say how much relaxation is
needed. Here the factor is searched exactly as sigma_F90 itself is (Sect. 3.3,
:func:`~mcsweep.experiments.f90_curve.sigma_f90_from_curve`): one global solution per
factor k of a grid (the prior ``k sigma_F90``, Eq. 18 with R sigma), the fraction of actual
position errors inside the P ellipse as a function of k for every cell (G class x subset
<= 4 / > 4 transits), and the smallest k at which the curve reaches P (linear in log k
between the bracketing grid points). Its interval is the bootstrap over the cell's stars
of :func:`~mcsweep.experiments.f90_curve.sigma_f90_interval` (one resample serves every
k, so the curve keeps its correlation). The factor for the whole solution is the
largest cell value: the smallest k that keeps P inside in every cell.

Every k costs one global solution, so the grid is coarse (a few values); a crossing is
only as good as the grid around it, and the flags say when it falls outside.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ..global_solution.table import SUBSETS, fraction_from_counts, g_label
from .reduction import TableReduction, reduce_parts

__all__ = ["FACTOR_COLUMNS", "CURVE_COLUMNS", "factor_label", "factor_curves", "factor_rows", "curves_from_reduction",
           "rows_from_reduction", "overall_factor"]

FACTOR_COLUMNS = ("subset", "g_class", "n_valid", "k_min", "flag", "k_lo", "k_hi")
CURVE_COLUMNS = ("subset", "g_class", "k", "n_valid", "n_inside", "fraction_inside", "fraction_lo", "fraction_hi")


def factor_label(k: float) -> str:
    """The ``priors`` entry of factor ``k`` (``'3F90'``; ``'F90'`` for 1), so solutions are shared with Table 3's."""
    return "F90" if float(k) == 1.0 else f"{float(k):g}F90"


def _reduced(results: Mapping[float, pd.DataFrame], g_classes: Sequence[float], confidence: float,
             count: str) -> TableReduction:
    """The cells of solutions held whole (one part each; factor k -> per-star results)."""
    labels = {float(k): factor_label(k) for k in results}
    parts = {labels[float(k)]: df for k, df in results.items()}
    return reduce_parts(lambda _: parts, 1, TableReduction(list(parts), g_classes, confidence, count=count,
                                                          factors=labels, ranked=()))


def factor_curves(results: Mapping[float, pd.DataFrame], g_classes: Sequence[float], count: str = "n_fov"
                  ) -> pd.DataFrame:
    """Fraction inside per cell and factor, with its Clopper-Pearson interval (Table 2's
    :func:`~mcsweep.experiments.secondary.table.fraction_statistics`), from solutions held
    whole: :func:`curves_from_reduction`."""
    return curves_from_reduction(_reduced(results, g_classes, 0.9, count))


def curves_from_reduction(reduction: TableReduction) -> pd.DataFrame:
    """:func:`factor_curves` from the cells of solutions read part by part
    (:class:`~mcsweep.experiments.primary.reduction.TableReduction` with its ``factors``)."""
    rows = [(subset, g_label(g), k, n_val, n_in, *fraction_from_counts(n_in, n_val))
            for subset in SUBSETS for g in reduction.g_classes
            for k, (n_val, n_in) in zip(reduction.factors, reduction.factor_counts(subset, g))]
    return pd.DataFrame(rows, columns=list(CURVE_COLUMNS))


def factor_rows(results: Mapping[float, pd.DataFrame], g_classes: Sequence[float], confidence: float, *,
                n_resamples: int, rng: np.random.Generator, count: str = "n_fov") -> pd.DataFrame:
    """Smallest k per cell (module notes) with flag and bootstrap interval.

    Parameters
    ----------
    results : mapping of factor k -> per-star results of that solution
        (:func:`mcsweep.experiments.primary.prior_solution.solve_prior`, prior ``k sigma_F90``).
    g_classes : the magnitude classes.
    confidence : P.
    n_resamples : bootstrap resamples (0: no interval).
    rng : generator of the bootstrap.
    count : the column counting transits for the subsets
        (:data:`~mcsweep.experiments.primary.table.SUBSET_COUNTS`).
    """
    return rows_from_reduction(_reduced(results, g_classes, confidence, count), n_resamples=n_resamples, rng=rng)


def rows_from_reduction(reduction: TableReduction, *, n_resamples: int, rng: np.random.Generator) -> pd.DataFrame:
    """:func:`factor_rows` from the cells of solutions read part by part: the bootstrap
    draws over the cell's patterns of flags, which is the bootstrap over its stars
    (:func:`~mcsweep.experiments.f90_curve.pattern_fractions`), the same bits."""
    rows = []
    for subset in SUBSETS:
        for g in reduction.g_classes:
            n_val, k_min, flag, lo, hi = reduction.factor_crossing(subset, g, n_resamples=n_resamples, rng=rng)
            rows.append((subset, g_label(g), n_val, k_min, flag, lo, hi))
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
