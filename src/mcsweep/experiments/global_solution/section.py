"""The part every global experiment's report section shares (paper Sect. 4, Tables 2 and 3).

A global experiment's section (:mod:`mcsweep.experiments.secondary.section`,
:mod:`mcsweep.experiments.primary.section`) reads the run's config from provenance
(:func:`section_config`) and hands :func:`global_section` what is its own (description,
table file and layout, the rows of its headline, the documented cause of a difference,
its diagnostics). The section then reads as every global experiment's does:

1. the headline: the fractions inside the P ellipse of the headline rows, ours with
   their Clopper-Pearson interval against the paper's (:func:`key_numbers`), how many
   cells have the paper's value outside our interval, and one sentence on the cell that
   differs most and its documented cause (:func:`difference_sentence`);
2. the setup (description, the reference epoch the run resolved to, provenance
   ``derived.<kind>``) and the table in the paper's layout, one table per subset of stars
   headed by their counts per class (the layout of ``table2.md`` / ``table3.md``,
   :mod:`mcsweep.experiments.global_solution.table`);
3. the experiment's diagnostics (summaries, figures).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from ...errors import UserInputError
from .priors import parse_prior
from .table import FRACTION_INTERVAL, SUBSET_TITLES, g_label, subset_counts, table_cell
from ...runtime.document import Document, plain
from ..scanning_note import extrapolation_para

__all__ = ["section_config", "global_section", "key_numbers", "difference_sentence", "largest_difference",
           "find_row", "readable_table"]

#: A cause of a difference: (the cell that differs most, the run's table) -> the text after
#: the colon of the difference sentence.
Cause = Callable[[pd.Series, pd.DataFrame], str]


def section_config(prov: dict, kind: str) -> tuple[dict, dict, float]:
    """(the run's config, its ``experiment.<kind>`` section, the confidence level P)."""
    cfg = prov.get("config", {})
    return cfg, cfg.get("experiment", {}).get(kind, {}), float(cfg.get("confidence", 0.9))


def _same_prior(a: str, b: str) -> bool:
    """'F90' and '1F90' name the same solution; 'none' is not in the prior grammar."""
    try:
        return parse_prior(a) == parse_prior(b)
    except UserInputError:
        return a == b


def find_row(table: pd.DataFrame, subset: str, prior: str, g_class) -> pd.Series | None:
    """The table's row of one cell (``prior`` in any spelling of the grammar), None if absent."""
    hit = table[(table["subset"] == subset) & (table["g_class"].astype(float) == float(g_class))
                & table["prior"].map(lambda p: _same_prior(str(p), prior))]
    return None if hit.empty else hit.iloc[0]


def _fraction(row: pd.Series) -> str:
    """A fraction as the tables print it: ``ours [lo-hi] (paper)`` in per cent."""
    iv = (row["fraction_lo"], row["fraction_hi"]) if "fraction_lo" in row else None
    return table_cell(row["fraction_inside"], row["paper_fraction_inside"], ".1f", 100.0, iv)


def _comparable(table: pd.DataFrame) -> pd.DataFrame:
    """Cells with both our fraction and the paper's; ``diff`` = ours - paper."""
    ok = np.isfinite(table["fraction_inside"].astype(float)) & np.isfinite(table["paper_fraction_inside"].astype(float))
    part = table[ok].copy()
    part["diff"] = part["fraction_inside"] - part["paper_fraction_inside"]
    return part


def _outside(row: pd.Series) -> bool | None:
    """Whether the paper's fraction lies outside our interval; None without an interval."""
    lo, hi = row.get("fraction_lo", math.nan), row.get("fraction_hi", math.nan)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return None
    return not (lo <= row["paper_fraction_inside"] <= hi)


def key_numbers(table: pd.DataFrame, p: float, priors: Sequence[str], label: Callable[[str], str],
                priors_setting: str | None = None) -> tuple[str, list[str]]:
    """(the lead-in, the bullets): per headline prior its fractions per subset and class,
    then how many cells have the paper's value outside our interval."""
    classes = list(dict.fromkeys(table["g_class"]))
    subsets = list(dict.fromkeys(table["subset"]))
    lead = (f"Fraction of stars inside the {100 * p:g} % confidence ellipse in per cent, ours "
            f"[{100 * FRACTION_INTERVAL:g} % Clopper-Pearson interval] (paper), for "
            f"G ~ {' / '.join(plain(g_label(g)) for g in classes)}:")
    items = []
    for prior in priors:
        parts = []
        for subset in subsets:
            rows = [find_row(table, subset, prior, g) for g in classes]
            if any(r is not None for r in rows):
                parts.append(f"{SUBSET_TITLES.get(subset, subset)} transits "
                             + " / ".join("–" if r is None else _fraction(r) for r in rows))
        if parts:
            items.append(f"{label(prior)}: " + "; ".join(parts))
        else:
            # A row of the paper's table this run did not solve (e.g. a subset of the priors).
            items.append(f"{label(prior)}: not in this run"
                         + (f" (`{priors_setting}`)" if priors_setting else ""))
    comp = _comparable(table)
    flags = [_outside(r) for _, r in comp.iterrows()]
    judged = [f for f in flags if f is not None]
    if comp.empty:
        items.append(f"No cell can be compared with the paper, whose values are for P = 0.9 and "
                     f"G ~ 11 / 15 / 19 (this run: P = {p:g}, G ~ {' / '.join(plain(g_label(g)) for g in classes)}).")
    elif judged:
        items.append(f"The paper's fraction lies outside our {100 * FRACTION_INTERVAL:g} % interval in "
                     f"{sum(judged)} of {len(judged)} cells.")
    return lead, items


def largest_difference(table: pd.DataFrame) -> pd.Series | None:
    """The comparable cell with the largest |ours - paper| fraction (the first in the table's
    order on a tie), with its ``diff``; None when no cell is comparable."""
    comp = _comparable(table)
    return None if comp.empty else comp.loc[comp["diff"].abs().idxmax()]


def difference_sentence(table: pd.DataFrame, label: Callable[[str], str], cause: Cause) -> str:
    """One sentence: the cell that differs most from the paper, by how much against our
    interval, and (only when the paper's value is outside it) the documented cause."""
    cell = largest_difference(table)
    if cell is None:
        return "No cell of this run can be compared with the paper's table."
    outside = _outside(cell)
    text = (f"Largest difference from the paper: {label(str(cell['prior']))}, "
            f"{SUBSET_TITLES.get(cell['subset'], cell['subset'])} transits, G ~ {plain(g_label(cell['g_class']))}, "
            f"{100 * cell['fraction_inside']:.1f}"
            + (f" [{100 * cell['fraction_lo']:.1f}-{100 * cell['fraction_hi']:.1f}]" if outside is not None else "")
            + f" % against {100 * cell['paper_fraction_inside']:.1f} % ({100 * cell['diff']:+.1f} points")
    if outside is False:
        return (text + f"), within our {100 * FRACTION_INTERVAL:g} % interval, so not distinguishable from this "
                "run's Monte Carlo noise.")
    where = f", outside our {100 * FRACTION_INTERVAL:g} % interval)" if outside else "; no interval recorded)"
    return text + where + f": {cause(cell, table)}."


def readable_table(doc: Document, df: pd.DataFrame, caption: str, floatfmt: dict | None = None,
                   names: dict[str, str] | None = None) -> None:
    """A table of a result file with headers a person reads and a browser can wrap: ``names``
    where given, else the file's column name with spaces for underscores (``floatfmt`` by
    the file's names)."""
    header = {c: (names or {}).get(c, str(c).replace("_", " ")) for c in df.columns}
    doc.table(df.rename(columns=header), caption, {header[c]: f for c, f in (floatfmt or {}).items() if c in header})


def global_section(doc: Document, run_dir: Path, prov: dict, *, kind: str, heading: str, description: str,
                   table_file: str, layout: Callable, caption: str, table_name: str,
                   headline_priors: Sequence[str], label: Callable[[str], str], cause: Cause,
                   priors_setting: str | None = None,
                   diagnostics: Callable[[Document, pd.DataFrame], None] | None = None) -> pd.DataFrame:
    """Add a global experiment's section in the shared order (module notes); returns its table.

    ``layout(table, P)`` gives the paper's layout per subset; ``caption`` names a subset's
    table, with ``{subset}`` for the subset (``'<= 4'``, ``'> 4'``). ``headline_priors``: the
    rows of the headline, in order, named as the table's ``prior`` column; ``label`` names
    a row as the paper does; ``priors_setting`` is the setting that chooses the rows (named
    when a headline row is missing); ``cause`` explains the largest difference;
    ``diagnostics(doc, table)`` adds the experiment's summaries and figures.
    """
    _, section, p = section_config(prov, kind)
    table = pd.read_csv(Path(run_dir) / table_file)
    doc.heading(heading)
    lead, items = key_numbers(table, p, headline_priors, label, priors_setting)
    doc.para(lead)
    doc.bullets(items)
    doc.para(difference_sentence(table, label, cause))
    extrapolation_para(doc, prov)

    doc.heading(f"{table_name} in the paper's layout", level=3)
    doc.para(description)
    # Runs made before the setting existed referred each star to its own mean epoch.
    epoch = prov.get("derived", {}).get(kind, {}).get("reference_epoch", {})
    doc.para(f"Reference epoch: {epoch.get('text') or section.get('reference_epoch', 'star_mean (not recorded)')}.")
    for subset, df in layout(table, p).items():
        doc.table(df, f"{caption.format(subset=SUBSET_TITLES[subset])} ({subset_counts(table, subset)} stars)")
    if diagnostics is not None:
        doc.heading("Diagnostics", level=3)
        diagnostics(doc, table)
    return table
