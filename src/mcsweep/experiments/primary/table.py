"""Table 3 of the paper (one-year global solution): the published values and ours.

Michalik et al. (2015), Table 3 ("Global astrometric solutions using 12 months of
simulated Gaia data. The attitude is determined as part of the solution"): per subset
(<= 4, > 4 FoV transits), prior and class (G ~ 11, 15, 19), the fraction of actual
position errors inside the 90 % confidence ellipse and the 90th percentile of the
actual position errors [mas]. Layout and columns as Table 2
(:mod:`mcsweep.experiments.global_solution.table`); here the transits are all those of one
year minus the dead time (no dilution).

Uncertainties exactly as Table 2's: every fraction carries its Clopper-Pearson interval
(:func:`~mcsweep.astrometry.confidence.binomial_interval`, probability
:data:`~mcsweep.experiments.global_solution.table.FRACTION_INTERVAL`) over the stars with a
confidence region in the cell, and every percentile of the errors its distribution-free
order-statistic (rank) interval of the same probability
(:func:`~mcsweep.astrometry.confidence.percentile_interval`). The paper gives no
uncertainties; at its 5e5 stars per class the binomial sigma of a 90 % fraction is 0.04 %
or more (fewer stars per subset).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ...astrometry.confidence import percentile_interval
from .reduction import TableReduction, reduce_parts
from ..global_solution.priors import prior_label
from ..global_solution.table import (FRACTION_INTERVAL, PAPER_G_CLASSES, SUBSETS, error_percentile, fraction_statistics,
                           g_label, layout_markdown, paper_layout, published_value)

__all__ = ["PAPER_TABLE3", "PAPER_G_CLASSES", "TABLE3_COLUMNS", "SUBSET_COUNTS", "paper_value3",
           "cell_statistics", "table3_rows", "table3_from_reduction", "table3_layout", "table3_markdown"]

#: Table 3 transcribed from the LaTeX source: (subset, prior) -> (fractions in per cent
#: for G ~ 11, 15, 19; 90th percentiles of the position errors in mas).
PAPER_TABLE3: Mapping[tuple[str, str], tuple[tuple[float, ...], tuple[float, ...]]] = MappingProxyType({
    ("<=4", "F90"): ((76.5, 86.8, 92.4), (1.2, 0.7, 2.0)),
    ("<=4", "10F90"): ((89.1, 90.4, 94.3), (1.4, 1.1, 4.2)),
    ("<=4", "1000mas"): ((89.7, 89.8, 90.6), (3.8, 3.4, 17.7)),
    (">4", "F90"): ((32.3, 53.3, 88.0), (0.2, 0.2, 0.8)),
    (">4", "10F90"): ((88.6, 89.3, 90.4), (0.1, 0.2, 1.0)),
    (">4", "1000mas"): ((88.7, 89.4, 90.0), (0.1, 0.2, 1.1)),
})
TABLE3_COLUMNS = ("subset", "prior", "g_class", "n_stars", "n_valid", "n_inside", "fraction_inside",
                  "fraction_lo", "fraction_hi", "p90_error_mas", "p90_error_lo_mas", "p90_error_hi_mas",
                  "paper_fraction_inside", "paper_p90_error_mas", "error_percentile")


#: ``experiment.primary.subset_transits`` -> the per-star column that counts a star's FoV
#: transits for the <= 4 / > 4 subsets: those observed (after the dead time, the default) or
#: those the scanning law scheduled (the paper's Sect. 4.2 and Table 3 do not say which).
SUBSET_COUNTS: Mapping[str, str] = MappingProxyType({"live": "n_fov", "scheduled": "n_fov_scheduled"})


def paper_value3(subset: str, prior: str, g_class: float, confidence: float) -> tuple[float, float]:
    """(fraction, 90th percentile [mas]) of the paper's Table 3, NaN where not comparable
    (:func:`~mcsweep.experiments.global_solution.table.published_value`; '1F90' is its sigma_F90 row)."""
    return published_value(PAPER_TABLE3, subset, "F90" if prior == "1F90" else prior, g_class, confidence)


def cell_statistics(inside: np.ndarray, err_mas: np.ndarray, confidence: float) -> tuple:
    """(n_valid, n_inside, fraction, fraction_lo, fraction_hi, percentile, percentile_lo, percentile_hi).

    ``inside``: per-star flags (1 inside, 0 outside, -1 no confidence region: left out,
    the NaN rule of :func:`~mcsweep.astrometry.confidence.inside_counts`); ``err_mas``: the
    position errors. Fraction with its Clopper-Pearson interval
    (:func:`~mcsweep.experiments.global_solution.table.fraction_statistics`, Table 2's), the
    100 P-th percentile of the errors with its rank interval, both of probability
    ``FRACTION_INTERVAL``.
    """
    n_valid, n_in, frac, lo, hi = fraction_statistics(inside)
    q = error_percentile(confidence)
    err = np.asarray(err_mas, dtype=float)[np.asarray(inside) >= 0]
    p = float(np.percentile(err, q)) if n_valid else float("nan")
    plo, phi = percentile_interval(err, q, FRACTION_INTERVAL)
    return n_valid, n_in, frac, lo, hi, p, plo, phi


def table3_rows(results: Mapping[str, pd.DataFrame], g_classes: Sequence[float], confidence: float,
                converged: Mapping[str, bool] | None = None, count: str = "n_fov") -> pd.DataFrame:
    """``table3.csv``: one row per subset x prior x class (extra primary sources are not tabulated).

    ``results[prior]`` holds the per-star results of one solution (columns ``class_key``,
    ``n_fov``, ``inside``, ``err_mas``; :func:`mcsweep.experiments.primary.prior_solution.solve_prior`).
    ``converged[prior]``: whether its solution met the PCG criterion (column ``converged``;
    only with ``experiment.primary.allow_unconverged`` can a False reach the table).
    ``count``: the column counting transits for the subsets (:data:`SUBSET_COUNTS`).
    The results held whole: :func:`table3_from_reduction` of their one part.
    """
    reduction = reduce_parts(lambda _: results, 1, TableReduction(list(results), g_classes, confidence, count=count))
    return table3_from_reduction(reduction, list(results), converged)


def table3_from_reduction(reduction: TableReduction, priors: Sequence[str],
                          converged: Mapping[str, bool] | None = None) -> pd.DataFrame:
    """:func:`table3_rows` from the cells of solutions read part by part
    (:class:`~mcsweep.experiments.primary.reduction.TableReduction`, whose stars may never be in
    memory at once): the same rows, bit for bit."""
    q = error_percentile(reduction.confidence)
    rows = []
    for subset in SUBSETS:
        for prior in priors:
            for g in reduction.g_classes:
                n_stars, *stats = reduction.cell_statistics(prior, subset, g)
                pf, pp = paper_value3(subset, prior, g, reduction.confidence)
                rows.append((subset, prior, g_label(g), n_stars, *stats, pf, pp, q))
    table = pd.DataFrame(rows, columns=list(TABLE3_COLUMNS))
    if converged is not None:
        table["converged"] = table["prior"].map(lambda p: bool(converged[p]))
    return table


def table3_layout(table: pd.DataFrame, confidence: float) -> dict[str, pd.DataFrame]:
    """Per subset: priors x (fraction | percentile) per class, ``ours [lo-hi] (paper)``: Table 2's
    :func:`~mcsweep.experiments.global_solution.table.paper_layout`, the priors in the table's order."""
    failed = set(table.loc[~table["converged"], "prior"]) if "converged" in table else set()
    return paper_layout(table, confidence, list(dict.fromkeys(table["prior"])),
                        lambda p: prior_label(p) + (" (NOT converged)" if p in failed else ""))


def table3_markdown(table: pd.DataFrame, confidence: float, notes: Sequence[str] = ()) -> str:
    """``table3.md``: our Table 3 next to the paper's (in parentheses)."""
    return layout_markdown("Table 3: one-year global solution, attitude from the same data (ours [68 % interval], "
                           "paper in parentheses)", notes, table, table3_layout(table, confidence))
