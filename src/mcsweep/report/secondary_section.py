"""Report section of the secondary-solution experiment (paper Sect. 4.1, Table 2).

Reads ``table2.csv``, ``no_prior.csv`` and ``secondary_summary.csv`` of a run
directory (written by :func:`mcsweep.sweep.secondary_runner.run_secondary`) and adds our
Table 2 next to the paper's (:func:`~mcsweep.report.global_section.global_section`), the
five-parameter solution without prior, and the per-class statistics of the diluted
observation histories.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..experiments.secondary_table import table2_layout
from .document import Document
from .global_section import global_section, section_config

__all__ = ["secondary_section"]


def secondary_section(doc: Document, run_dir: Path, prov: dict) -> None:
    """Add the Table 2 section to ``doc`` (see module notes)."""
    run_dir = Path(run_dir)
    cfg, sec, p = section_config(prov, "secondary")
    summary = pd.read_csv(run_dir / "secondary_summary.csv")
    global_section(
        doc, run_dir, prov, kind="secondary",
        heading="Secondary solution of stars with diluted histories (paper Sect. 4.1, Table 2)",
        description=(
            f"{len(summary)} magnitude classes of {int(summary['n_stars'].max())} stars each (the brightest "
            f"over the whole sky fainter than G = {', '.join(map(str, summary['g_class']))}); "
            f"{sec.get('mission_years')} years of FoV transits from {sec.get('mission_start')} (TCB) with the "
            f"'{cfg.get('scanning', {}).get('name')}' scanning law, each transit removed with probability "
            f"{sec.get('dilution')}; attitude known. Priors: sigma_F90 from '{sec.get('f90_formula')}', "
            f"R = {cfg.get('ratio_R')} /yr. Fractions are inside the P = {p:g} confidence ellipse; errors are "
            f"the {100 * p:g}th percentile of |estimated - true position| at the reference epoch (the paper's "
            "values are shown only at its P = 0.9). Each cell: ours (paper)."),
        table_file="table2.csv", layout=table2_layout,
        caption="Table 2, stars with {subset} retained field-of-view transits")
    no_prior_file = run_dir / "no_prior.csv"
    if no_prior_file.exists():
        doc.table(pd.read_csv(no_prior_file),
                  "Five-parameter solution without prior: stars it cannot solve (singular or condition "
                  f"number > 1e6) and, for the others, fraction inside and {100 * p:g}th percentile [mas]",
                  {"fraction_unsolved": ".3f", "fraction_inside": ".3f", "p90_error_mas": ".3g"})
    cols = ["g_class", "n_stars", "g_faintest", "mean_transits_undiluted", "mean_fov_retained",
            "mean_fov_retained_observed", "n_no_transit", "n_le4", "n_gt4", "median_sigma_f90_mas"]
    doc.table(summary[[c for c in cols if c in summary]],
              "Observation histories per class (paper: ~4.4 retained transits per star on average)",
              {"g_faintest": ".4f", "mean_transits_undiluted": ".1f", "mean_fov_retained": ".2f",
               "mean_fov_retained_observed": ".2f", "median_sigma_f90_mas": ".3g"})
    unsolved = [c for c in summary.columns if c.startswith("n_unsolved_") and c != "n_unsolved_no_prior"]
    bad = summary[unsolved].to_numpy().sum() if unsolved else 0
    if bad:
        doc.para(f"Warning: {int(bad)} prior or position-only solutions were singular and are left out of "
                 "the fractions (columns n_unsolved_* of secondary_summary.csv).")
