"""The part every global experiment's report section shares (paper Sect. 4, Tables 2 and 3).

A global experiment's section (:mod:`mcsweep.report.secondary_section`,
:mod:`mcsweep.report.primary_section`) reads the run's config from provenance
(:func:`section_config`), then :func:`global_section` adds the heading, the
experiment's own description, the reference epoch it resolved to (provenance
``derived.<kind>``) and its table in the paper's layout, one table per subset of stars
headed by their counts per class (the layout of ``table2.md`` / ``table3.md``,
:mod:`mcsweep.experiments.global_table`). What follows (summaries, figures) is the
experiment's own.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import pandas as pd

from ..experiments.global_table import SUBSET_TITLES, subset_counts
from .document import Document

__all__ = ["section_config", "global_section"]


def section_config(prov: dict, kind: str) -> tuple[dict, dict, float]:
    """(the run's config, its ``experiment.<kind>`` section, the confidence level P)."""
    cfg = prov.get("config", {})
    return cfg, cfg.get("experiment", {}).get(kind, {}), float(cfg.get("confidence", 0.9))


def global_section(doc: Document, run_dir: Path, prov: dict, *, kind: str, heading: str, description: str,
                   table_file: str, layout: Callable, caption: str) -> pd.DataFrame:
    """Add the shared part of a global experiment's section (module notes); returns its table.

    ``layout(table, P)`` gives the paper's layout per subset; ``caption`` names a subset's
    table, with ``{subset}`` for the subset (``'<= 4'``, ``'> 4'``).
    """
    _, section, p = section_config(prov, kind)
    table = pd.read_csv(Path(run_dir) / table_file)
    doc.heading(heading)
    doc.para(description)
    # Runs made before the setting existed referred each star to its own mean epoch.
    epoch = prov.get("derived", {}).get(kind, {}).get("reference_epoch", {})
    doc.para(f"Reference epoch: {epoch.get('text') or section.get('reference_epoch', 'star_mean (not recorded)')}.")
    for subset, df in layout(table, p).items():
        doc.table(df, f"{caption.format(subset=SUBSET_TITLES[subset])} ({subset_counts(table, subset)} stars)")
    return table
