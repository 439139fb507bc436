"""Table 2 of the paper: its rows, the published values, and ours from per-star results.

Michalik, Lindegren, Hobbs & Butkevich (2015, A&A 583, A68), Table 2 ("Simulation
results for stars with 95 % diluted five year observation histories"), in the layout of
:mod:`mcsweep.experiments.global_solution.table` (shared with Table 3); the headings say the
dilution of the run, not the paper's 95 %.

The per-star results (one row per star, written by :mod:`mcsweep.experiments.secondary.experiment`)
carry, per solution, ``inside_<col>`` (1 inside the P ellipse, 0 outside, -1 no
solution) and ``err_<col>_mas`` (|estimated - true position|, NaN without solution).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ..global_solution.priors import prior_label
from ..global_solution.table import (PAPER_CONFIDENCE, SUBSETS, error_percentile, fraction_statistics, g_label, layout_markdown,
                           paper_layout, published_value, subset_masks)

__all__ = [
    "PRIORS",
    "SOLUTION_COLUMNS",
    "PRIOR_LABELS",
    "PAPER_TABLE2",
    "TABLE2_COLUMNS",
    "NO_PRIOR_COLUMNS",
    "paper_value",
    "table2_rows",
    "no_prior_rows",
    "table2_layout",
    "table2_markdown",
]

#: The rows of Table 2, in the paper's order (values of the ``prior`` column): position
#: only, then the priors (:mod:`mcsweep.experiments.global_solution.priors`).
PRIORS = ("none", "0.01mas", "F90", "10F90", "1000mas")
#: Column stem of each solution in the per-star results ("5p" = five parameters, no prior).
SOLUTION_COLUMNS: Mapping[str, str] = MappingProxyType({
    "none": "none", "0.01mas": "tight", "F90": "f90", "10F90": "f90x10", "1000mas": "loose",
    "5p": "no_prior"})
#: Row labels of the paper's first column.
PRIOR_LABELS: Mapping[str, str] = MappingProxyType({
    "none": "none (2 parameters)", **{p: prior_label(p) for p in PRIORS[1:]}})
#: Table 2 of the paper, transcribed from the LaTeX source: (subset, prior) ->
#: (fraction in the 90 % ellipse in per cent for G ~ 11, 15, 19;
#:  90th percentile of the actual position errors in mas for G ~ 11, 15, 19).
PAPER_TABLE2: Mapping[tuple[str, str], tuple[tuple[float, ...], tuple[float, ...]]] = MappingProxyType({
    ("<=4", "none"): ((0.5, 1.8, 13.5), (33.0, 16.3, 15.2)),
    ("<=4", "0.01mas"): ((1.5, 3.5, 14.3), (21.8, 12.1, 14.8)),
    ("<=4", "F90"): ((90.1, 91.4, 91.2), (7.6, 4.3, 7.6)),
    ("<=4", "10F90"): ((92.7, 93.3, 94.4), (8.4, 5.2, 10.5)),
    ("<=4", "1000mas"): ((92.5, 93.0, 93.3), (8.6, 7.4, 15.5)),
    (">4", "none"): ((0.3, 0.8, 8.6), (21.0, 11.3, 9.7)),
    (">4", "0.01mas"): ((3.1, 5.4, 10.4), (6.7, 5.0, 8.9)),
    (">4", "F90"): ((89.4, 89.9, 90.3), (0.2, 0.3, 1.6)),
    (">4", "10F90"): ((89.5, 89.8, 90.5), (0.2, 0.3, 2.0)),
    (">4", "1000mas"): ((89.5, 89.8, 90.0), (0.2, 0.3, 2.2)),
})

#: Columns of ``table2.csv``, in order.
TABLE2_COLUMNS = ("subset", "prior", "g_class", "n_stars", "fraction_inside", "p90_error_mas",
                  "paper_fraction_inside", "paper_p90_error_mas", "error_percentile", "fraction_lo",
                  "fraction_hi")
#: Columns of ``no_prior.csv`` (five-parameter solution without prior), in order.
NO_PRIOR_COLUMNS = ("subset", "g_class", "n_stars", "n_unsolved", "fraction_unsolved",
                    "fraction_inside", "p90_error_mas", "error_percentile")


def paper_value(subset: str, prior: str, g_class: float, confidence: float) -> tuple[float, float]:
    """(fraction inside, 90th percentile in mas) of the paper's Table 2, NaN where not comparable
    (:func:`~mcsweep.experiments.global_solution.table.published_value`)."""
    return published_value(PAPER_TABLE2, subset, prior, g_class, confidence)


def _stats(stars: pd.DataFrame, sel: np.ndarray, col: str, percentile: float) -> tuple:
    """``fraction_statistics`` of a selection and the ``percentile``-th percentile of its valid errors."""
    inside = stars[f"inside_{col}"].to_numpy()[sel]
    err = stars[f"err_{col}_mas"].to_numpy()[sel].astype(np.float64)
    stats = fraction_statistics(inside)
    p90 = float(np.percentile(err[inside >= 0], percentile)) if stats[0] else float("nan")
    return (*stats, p90)


def table2_rows(per_class: Sequence[tuple[float, pd.DataFrame]], confidence: float) -> pd.DataFrame:
    """``table2.csv``: one row per subset x prior x class, in the paper's order.

    Parameters
    ----------
    per_class : sequence of (g_class, per-star results)
    confidence : float
        Confidence level P of the ellipses the ``inside_*`` columns were computed with;
        the errors are summarised by their 100 P-th percentile.
    """
    q = error_percentile(confidence)
    rows = []
    masks = [(g, stars, subset_masks(stars["n_fov"].to_numpy())) for g, stars in per_class]
    for subset in SUBSETS:
        for prior in PRIORS:
            for g, stars, m in masks:
                _, _, frac, lo, hi, p90 = _stats(stars, m[subset], SOLUTION_COLUMNS[prior], q)
                pf, pp = paper_value(subset, prior, g, confidence)
                rows.append((subset, prior, g_label(g), int(m[subset].sum()), frac, p90, pf, pp, q, lo, hi))
    return pd.DataFrame(rows, columns=list(TABLE2_COLUMNS))


def no_prior_rows(per_class: Sequence[tuple[float, pd.DataFrame]], confidence: float = PAPER_CONFIDENCE) -> pd.DataFrame:
    """``no_prior.csv``: the five-parameter solution without prior, per subset and class.

    Errors are summarised by their 100 P-th percentile, P = ``confidence``.
    """
    q = error_percentile(confidence)
    rows = []
    for subset in SUBSETS:
        for g, stars in per_class:
            sel = subset_masks(stars["n_fov"].to_numpy())[subset]
            n_valid, _, frac, _, _, p90 = _stats(stars, sel, SOLUTION_COLUMNS["5p"], q)
            n = int(sel.sum())
            n_bad = n - n_valid
            rows.append((subset, g_label(g), n, n_bad, n_bad / n if n else float("nan"), frac, p90, q))
    return pd.DataFrame(rows, columns=list(NO_PRIOR_COLUMNS))


def table2_layout(table: pd.DataFrame, confidence: float) -> dict[str, pd.DataFrame]:
    """The paper's layout of ``table2.csv`` (:func:`paper_layout`; fractions with their
    Clopper-Pearson interval, FRACTION_INTERVAL)."""
    return paper_layout(table, confidence, PRIORS, PRIOR_LABELS.__getitem__)


def table2_markdown(table: pd.DataFrame, confidence: float, notes: Sequence[str] = (),
                    dilution: float = 0.95) -> str:
    """``table2.md``: our Table 2 next to the paper's (in parentheses), one table per subset.

    ``dilution`` is the run's probability of removing a transit (the paper's 95 %).
    """
    return layout_markdown(f"Table 2: stars with {100 * dilution:g} % diluted observation histories "
                           "(ours, paper in parentheses)", notes, table, table2_layout(table, confidence))
