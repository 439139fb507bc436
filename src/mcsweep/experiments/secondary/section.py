"""Report section of the secondary-solution experiment (paper Sect. 4.1, Table 2).

Reads ``table2.csv``, ``no_prior.csv`` and ``secondary_summary.csv`` of a run
directory (written by :func:`mcsweep.experiments.secondary.runner.run_secondary`). In the order of
:func:`~mcsweep.experiments.global_solution.section.global_section`: the headline (fractions of every
solution type against the paper's, the cell that differs most and its documented cause,
:func:`table2_cause`), our Table 2 next to the paper's, then the diagnostics: the
five-parameter solution without prior and the per-class statistics of the diluted
observation histories.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..global_solution.table import FRACTION_INTERVAL
from .table import PRIOR_LABELS, table2_layout
from ...runtime.document import Document, plain
from ..global_solution.section import find_row, global_section, readable_table, section_config

__all__ = ["secondary_section", "table2_cause", "HEADLINE_PRIORS"]

#: The headline's rows: the priors first, then the solutions the prior is compared with.
HEADLINE_PRIORS = ("F90", "10F90", "1000mas", "none", "0.01mas")
#: Where the known differences of Table 2 are written down.
_DOCS = "`docs/architecture.md`, 'Known modelling differences'; `docs/table2_epoch.md`"


def table2_cause(cell: pd.Series, table: pd.DataFrame) -> str:
    """The documented cause of a Table 2 cell's difference, with this run's numbers."""
    prior = str(cell["prior"])
    if prior in ("none", "0.01mas"):
        return ("these solutions are biased by the parallax and proper motion they leave out or pin to zero, so "
                "their fraction sets the population's motions against the noise model's formal errors, and "
                "neither our galaxy model nor our noise model is the paper's "
                "(`docs/table2_epoch.md`, 'Cells that still disagree', 3)")
    if float(cell["g_class"]) == 11.0:
        err = find_row(table, ">4", prior, 11)
        if err is not None and np.isfinite(err["p90_error_mas"]) and np.isfinite(err["paper_p90_error_mas"]):
            ratio = err["p90_error_mas"] / err["paper_p90_error_mas"]
            return (f"at G ~ 11 the measurements rather than the prior set the errors, and ours with more than "
                    f"4 transits are {ratio:.2f} x the paper's ({PRIOR_LABELS.get(prior, prior)}: "
                    f"{plain(err['p90_error_mas'], '.3g')} against {plain(err['paper_p90_error_mas'], 'g')} mas), "
                    "most likely because our bright stars' AC precision is better than the paper assumed "
                    f"({_DOCS})")
    return f"our galaxy model and noise model are not the paper's ({_DOCS})"


def secondary_section(doc: Document, run_dir: Path, prov: dict) -> None:
    """Add the Table 2 section to ``doc`` (see module notes)."""
    run_dir = Path(run_dir)
    cfg, sec, p = section_config(prov, "secondary")
    summary = pd.read_csv(run_dir / "secondary_summary.csv")

    def diagnostics(doc: Document, table: pd.DataFrame) -> None:
        no_prior_file = run_dir / "no_prior.csv"
        if no_prior_file.exists():
            readable_table(doc, pd.read_csv(no_prior_file),
                           "Five-parameter solution without prior: stars it cannot solve (singular or condition "
                           f"number > 1e6) and, for the others, fraction inside and {100 * p:g}th percentile [mas]",
                           {"fraction_unsolved": ".3f", "fraction_inside": ".3f", "p90_error_mas": ".3g"},
                           {"g_class": "G class", "p90_error_mas": f"p{100 * p:g} error [mas]"})
        cols = ["g_class", "n_stars", "g_faintest", "mean_transits_undiluted", "mean_fov_retained",
                "mean_fov_retained_observed", "n_no_transit", "n_le4", "n_gt4", "median_sigma_f90_mas"]
        readable_table(doc, summary[[c for c in cols if c in summary]],
                       "Observation histories per class (paper: ~4.4 retained transits per star on average)",
                       {"g_faintest": ".4f", "mean_transits_undiluted": ".1f", "mean_fov_retained": ".2f",
                        "mean_fov_retained_observed": ".2f", "median_sigma_f90_mas": ".3g"},
                       {"g_class": "G class", "g_faintest": "G faintest",
                        "mean_fov_retained": "mean FoV transits retained",
                        "mean_fov_retained_observed": "mean FoV transits retained, stars with any",
                        "n_le4": "n <= 4", "n_gt4": "n > 4", "median_sigma_f90_mas": "median sigma_F90 [mas]"})
        unsolved = [c for c in summary.columns if c.startswith("n_unsolved_") and c != "n_unsolved_no_prior"]
        bad = summary[unsolved].to_numpy().sum() if unsolved else 0
        if bad:
            doc.para(f"Warning: {int(bad)} prior or position-only solutions were singular and are left out of "
                     "the fractions (columns `n_unsolved_*` of `secondary_summary.csv`).")

    global_section(
        doc, run_dir, prov, kind="secondary",
        heading="Secondary solution of stars with diluted histories (paper Sect. 4.1, Table 2)",
        description=(
            f"{len(summary)} magnitude classes of {int(summary['n_stars'].max())} stars each (the brightest "
            f"over the whole sky fainter than G = {plain(summary['g_class'])}); "
            f"{plain(sec.get('mission_years'))} years of FoV transits from {sec.get('mission_start')} (TCB) with "
            f"the `{cfg.get('scanning', {}).get('name')}` scanning law, each transit removed with probability "
            f"{plain(sec.get('dilution'))}; attitude known. Priors: sigma_F90 from `{sec.get('f90_formula')}`, "
            f"R = {plain(cfg.get('ratio_R'))} /yr. Fractions are inside the P = {p:g} confidence ellipse; errors "
            f"are the {100 * p:g}th percentile of |estimated - true position| at the reference epoch (the "
            "paper's values are shown only at its P = 0.9). Each cell: ours (paper); fractions with their "
            f"{100 * FRACTION_INTERVAL:g} % Clopper-Pearson interval."),
        table_file="table2.csv", layout=table2_layout, table_name="Table 2",
        caption="Table 2, stars with {subset} retained field-of-view transits",
        headline_priors=HEADLINE_PRIORS, label=PRIOR_LABELS.__getitem__, cause=table2_cause,
        diagnostics=diagnostics)
