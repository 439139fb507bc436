"""Table 2 of the paper: the layout, the published values, and ours from per-star results.

Michalik, Lindegren, Hobbs & Butkevich (2015, A&A 583, A68), Table 2 ("Simulation
results for stars with 95 % diluted five year observation histories"): for the
subsets of stars with <= 4 and > 4 retained field-of-view transits, per prior and
magnitude class (G ~ 11, 15, 19), the fraction of actual position errors inside the
90 % confidence ellipse computed from the formal covariance, and the 90th percentile
of the actual position errors (estimated minus true position) in mas. Both follow the
run's confidence level P: the ellipse is the P one and the percentile the 100 P-th
(the F90 prior makes the P ellipse match the P-th percentile, Sect. 3.3), so the
headings say P and the dilution of the run, not the paper's 90 % and 95 %.

The per-star results (one row per star, written by :mod:`mcsweep.experiments.secondary`)
carry, per solution, ``inside_<col>`` (1 inside the P ellipse, 0 outside, -1 no
solution) and ``err_<col>_mas`` (|estimated - true position|, NaN without solution).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from ..astrometry.confidence import binomial_interval

__all__ = [
    "PRIORS",
    "SOLUTION_COLUMNS",
    "SUBSETS",
    "SUBSET_SPLIT",
    "PRIOR_LABELS",
    "PAPER_G_CLASSES",
    "PAPER_CONFIDENCE",
    "PAPER_TABLE2",
    "TABLE2_COLUMNS",
    "NO_PRIOR_COLUMNS",
    "paper_value",
    "subset_masks",
    "table2_rows",
    "no_prior_rows",
    "g_label",
    "table2_layout",
    "table2_markdown",
    "paper_layout",
    "layout_markdown",
    "error_percentile",
    "FRACTION_INTERVAL",
    "fraction_statistics",
    "table_cell",
]

#: The rows of Table 2, in the paper's order (values of the ``prior`` column).
PRIORS = ("none", "0.01mas", "F90", "10F90", "1000mas")
#: Column stem of each solution in the per-star results ("5p" = five parameters, no prior).
SOLUTION_COLUMNS: Mapping[str, str] = MappingProxyType({
    "none": "none", "0.01mas": "tight", "F90": "f90", "10F90": "f90x10", "1000mas": "loose",
    "5p": "no_prior"})
#: Subsets by number of retained FoV transits (values of the ``subset`` column).
SUBSETS = ("<=4", ">4")
#: Largest number of FoV transits of the first subset.
SUBSET_SPLIT = 4
#: Row labels of the paper's first column.
PRIOR_LABELS: Mapping[str, str] = MappingProxyType({
    "none": "none (2 parameters)", "0.01mas": "0.01 mas", "F90": "sigma_F90",
    "10F90": "10 sigma_F90", "1000mas": "1000 mas"})
#: The magnitude classes of Table 2.
PAPER_G_CLASSES = (11.0, 15.0, 19.0)
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
#: Probability of the Clopper-Pearson interval on each fraction (fraction_lo/hi).
FRACTION_INTERVAL = 0.68
#: Columns of ``no_prior.csv`` (five-parameter solution without prior), in order.
NO_PRIOR_COLUMNS = ("subset", "g_class", "n_stars", "n_unsolved", "fraction_unsolved",
                    "fraction_inside", "p90_error_mas", "error_percentile")

# The paper's confidence level; its fractions are comparable only at this P.
PAPER_CONFIDENCE = 0.9


def g_label(g: float):
    """A class's G as written in the tables: 11 rather than 11.0 for whole magnitudes."""
    g = float(g)
    return int(g) if g.is_integer() else g


def paper_value(subset: str, prior: str, g_class: float, confidence: float) -> tuple[float, float]:
    """(fraction inside, 90th percentile in mas) of the paper's Table 2, NaN where not comparable.

    Both are given only when ``confidence`` is the paper's 0.9 (a run at another P reports
    another ellipse and another percentile) and the class is one of :data:`PAPER_G_CLASSES`.
    """
    try:
        i = PAPER_G_CLASSES.index(float(g_class))
    except ValueError:
        return float("nan"), float("nan")
    frac_pct, p90 = PAPER_TABLE2[(subset, prior)]
    if abs(confidence - PAPER_CONFIDENCE) >= 1e-12:
        return float("nan"), float("nan")
    return frac_pct[i] / 100.0, p90[i]


def subset_masks(n_fov: np.ndarray) -> dict[str, np.ndarray]:
    """Stars with 1..4 and with more than 4 retained FoV transits (none: not solved)."""
    n_fov = np.asarray(n_fov)
    return {"<=4": (n_fov >= 1) & (n_fov <= SUBSET_SPLIT), ">4": n_fov > SUBSET_SPLIT}


def error_percentile(confidence: float) -> float:
    """The percentile of the actual errors reported at confidence level P: 100 P."""
    return 100.0 * float(confidence)


def fraction_statistics(inside) -> tuple[int, int, float, float, float]:
    """``(n_valid, n_inside, fraction, fraction_lo, fraction_hi)`` of one cell's per-star flags.

    ``inside``: 1 inside the P ellipse, 0 outside, -1 no confidence region (left out of
    the denominator, the NaN rule of :func:`~mcsweep.astrometry.confidence.inside_counts`;
    the flags were set per star by :func:`~mcsweep.astrometry.confidence.inside`). The
    fraction ``n_inside / n_valid`` (NaN without a valid star) with its Clopper-Pearson
    interval of probability :data:`FRACTION_INTERVAL`, computed from the integer counts.
    The cell statistics of Tables 2 and 3 and of the primary factor curves.
    """
    inside = np.asarray(inside)
    n_valid, n_in = int(np.count_nonzero(inside >= 0)), int(np.count_nonzero(inside == 1))
    frac = n_in / n_valid if n_valid else float("nan")
    lo, hi = binomial_interval(n_in, n_valid, FRACTION_INTERVAL)
    return n_valid, n_in, frac, float(lo), float(hi)


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


def table_cell(ours: float, paper: float, fmt: str, scale: float = 1.0, interval=None) -> str:
    """``ours [lo-hi] (paper)`` as the tables print a cell (interval and paper optional)."""
    o = "–" if not np.isfinite(ours) else format(ours * scale, fmt)
    if interval is not None and np.isfinite(ours) and np.all(np.isfinite(interval)):
        o += f" [{format(interval[0] * scale, fmt)}-{format(interval[1] * scale, fmt)}]"
    return o if not np.isfinite(paper) else f"{o} ({format(paper * scale, fmt)})"


def paper_layout(table: pd.DataFrame, confidence: float, priors: Sequence[str],
                 label: Callable[[str], str]) -> dict[str, pd.DataFrame]:
    """The paper's layout of a Table 2 / Table 3 csv: per subset, ``priors`` x (fraction |
    percentile) per class, each cell ``ours [lo-hi] (paper)``.

    Fractions in per cent, percentiles in mas; an interval is shown where the table has
    its columns (``fraction_lo/hi``, ``p90_error_lo/hi_mas``). ``label`` names a prior's row.
    """
    classes = list(dict.fromkeys(table["g_class"]))
    pct = f"{100 * confidence:g}"
    out = {}
    for subset in SUBSETS:
        part = table[table["subset"] == subset]
        rows = []
        for prior in priors:
            r = part[part["prior"] == prior].set_index("g_class")
            row = {"prior sigma_plx,p": label(prior)}
            for g in classes:
                iv = (r.at[g, "fraction_lo"], r.at[g, "fraction_hi"]) if "fraction_lo" in r else None
                row[f"in {pct} % ellipse, G~{g} [%]"] = table_cell(r.at[g, "fraction_inside"],
                                                                   r.at[g, "paper_fraction_inside"], ".1f", 100.0, iv)
            for g in classes:
                iv = (r.at[g, "p90_error_lo_mas"], r.at[g, "p90_error_hi_mas"]) if "p90_error_lo_mas" in r else None
                row[f"p{pct} error, G~{g} [mas]"] = table_cell(r.at[g, "p90_error_mas"],
                                                               r.at[g, "paper_p90_error_mas"], ".3g", 1.0, iv)
            rows.append(row)
        out[subset] = pd.DataFrame(rows)
    return out


def table2_layout(table: pd.DataFrame, confidence: float) -> dict[str, pd.DataFrame]:
    """The paper's layout of ``table2.csv`` (:func:`paper_layout`; fractions with their
    Clopper-Pearson interval, FRACTION_INTERVAL)."""
    return paper_layout(table, confidence, PRIORS, PRIOR_LABELS.__getitem__)


def layout_markdown(title: str, notes: Sequence[str], table: pd.DataFrame,
                    layout: Mapping[str, pd.DataFrame]) -> str:
    """A table's Markdown file: ``# title``, the notes, then one table per subset headed by
    its star counts per class (from ``table``'s ``n_stars``)."""
    counts = table.drop_duplicates(["subset", "g_class"]).set_index(["subset", "g_class"])["n_stars"]
    lines = [f"# {title}", ""]
    lines += [f"{n}" for n in notes]
    if notes:
        lines.append("")
    for subset, df in layout.items():
        n = ", ".join(f"G~{g}: {int(v)}" for (s, g), v in counts.items() if s == subset)
        heading = "<= 4" if subset == "<=4" else "> 4"
        lines += [f"## Subset of stars with {heading} field-of-view transits ({n} stars)", ""]
        cols = list(map(str, df.columns))
        lines += ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
        lines += ["| " + " | ".join(map(str, row)) + " |" for row in df.itertuples(index=False)] + [""]
    return "\n".join(lines)


def table2_markdown(table: pd.DataFrame, confidence: float, notes: Sequence[str] = (),
                    dilution: float = 0.95) -> str:
    """``table2.md``: our Table 2 next to the paper's (in parentheses), one table per subset.

    ``dilution`` is the run's probability of removing a transit (the paper's 95 %).
    """
    return layout_markdown(f"Table 2: stars with {100 * dilution:g} % diluted observation histories "
                           "(ours, paper in parentheses)", notes, table, table2_layout(table, confidence))
