"""The layout of the global experiments' tables (paper Tables 2 and 3) and their cell statistics.

Tables 2 and 3 of Michalik et al. (2015) share one layout: per subset of stars (<= 4 and
> 4 field-of-view transits), prior and magnitude class (G ~ 11, 15, 19), the fraction of
actual position errors inside the 90 % confidence ellipse computed from the formal
covariance, and the 90th percentile of the actual position errors (estimated minus true
position) in mas. Both follow the run's confidence level P: the ellipse is the P one and
the percentile the 100 P-th (the F90 prior makes the P ellipse match the P-th
percentile, Sect. 3.3), so the headings say P, not the paper's 90 %. Every fraction
carries its Clopper-Pearson interval of probability :data:`FRACTION_INTERVAL`; the
published value of a cell is shown only where comparable (the paper's P and classes).

A global experiment's table module holds what is its own (its rows, published values and
per-star columns) and lays its table out with :func:`paper_layout` and
:func:`layout_markdown`; the report shows the same layout (:mod:`mcsweep.experiments.global_solution.section`).
"""

from __future__ import annotations

from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from ...astrometry.confidence import binomial_interval

__all__ = ["SUBSETS", "SUBSET_SPLIT", "SUBSET_TITLES", "PAPER_G_CLASSES", "PAPER_CONFIDENCE",
           "FRACTION_INTERVAL", "g_label", "published_value", "subset_masks", "error_percentile",
           "fraction_statistics", "fraction_from_counts", "table_cell", "subset_counts", "paper_layout", "layout_markdown"]

#: Subsets by number of retained FoV transits (values of the ``subset`` column).
SUBSETS = ("<=4", ">4")
#: Largest number of FoV transits of the first subset.
SUBSET_SPLIT = 4
#: How the headings name the subsets.
SUBSET_TITLES = {"<=4": "<= 4", ">4": "> 4"}
#: The magnitude classes of Tables 2 and 3.
PAPER_G_CLASSES = (11.0, 15.0, 19.0)
# The paper's confidence level; its fractions are comparable only at this P.
PAPER_CONFIDENCE = 0.9
#: Probability of the Clopper-Pearson interval on each fraction (fraction_lo/hi).
FRACTION_INTERVAL = 0.68


def g_label(g: float):
    """A class's G as written in the tables: 11 rather than 11.0 for whole magnitudes."""
    g = float(g)
    return int(g) if g.is_integer() else g


def published_value(published: Mapping, subset: str, prior: str, g_class: float,
                    confidence: float) -> tuple[float, float]:
    """(fraction inside, 90th percentile in mas) of a published table, NaN where not comparable.

    ``published[(subset, prior)]`` = (fractions in per cent, percentiles in mas) for G ~
    11, 15, 19. Both are given only when ``confidence`` is the paper's 0.9 (a run at another
    P reports another ellipse and another percentile), the class is one of
    :data:`PAPER_G_CLASSES` and the paper has the row.
    """
    try:
        i = PAPER_G_CLASSES.index(float(g_class))
    except ValueError:
        return float("nan"), float("nan")
    if (subset, prior) not in published or abs(confidence - PAPER_CONFIDENCE) >= 1e-12:
        return float("nan"), float("nan")
    frac_pct, p90 = published[(subset, prior)]
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
    return (n_valid, n_in, *fraction_from_counts(n_in, n_valid))


def fraction_from_counts(n_inside: int, n_valid: int) -> tuple[float, float, float]:
    """``(fraction, fraction_lo, fraction_hi)`` of a cell from its counts (:func:`fraction_statistics`)."""
    lo, hi = binomial_interval(n_inside, n_valid, FRACTION_INTERVAL)
    return (n_inside / n_valid if n_valid else float("nan")), float(lo), float(hi)


def table_cell(ours: float, paper: float, fmt: str, scale: float = 1.0, interval=None) -> str:
    """``ours [lo-hi] (paper)`` as the tables print a cell (interval and paper optional)."""
    o = "–" if not np.isfinite(ours) else format(ours * scale, fmt)
    if interval is not None and np.isfinite(ours) and np.all(np.isfinite(interval)):
        o += f" [{format(interval[0] * scale, fmt)}-{format(interval[1] * scale, fmt)}]"
    return o if not np.isfinite(paper) else f"{o} ({format(paper * scale, fmt)})"


def subset_counts(table: pd.DataFrame, subset: str) -> str:
    """``'G~11: 2874, G~15: ...'``: a subset's stars per class (``n_stars`` of the table)."""
    part = table[table["subset"] == subset].drop_duplicates("g_class")
    return ", ".join(f"G~{g}: {int(v)}" for g, v in zip(part["g_class"], part["n_stars"]))


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


def layout_markdown(title: str, notes: Sequence[str], table: pd.DataFrame,
                    layout: Mapping[str, pd.DataFrame]) -> str:
    """A table's Markdown file: ``# title``, the notes, then one table per subset headed by
    its star counts per class (from ``table``'s ``n_stars``)."""
    lines = [f"# {title}", ""]
    lines += [f"{n}" for n in notes]
    if notes:
        lines.append("")
    for subset, df in layout.items():
        lines += [f"## Subset of stars with {SUBSET_TITLES[subset]} field-of-view transits "
                  f"({subset_counts(table, subset)} stars)", ""]
        cols = list(map(str, df.columns))
        lines += ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
        lines += ["| " + " | ".join(map(str, row)) + " |" for row in df.itertuples(index=False)] + [""]
    return "\n".join(lines)
