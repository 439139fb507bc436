"""Report section of the one-year global (primary) experiment (paper Sect. 4.2, Table 3).

Reads ``table3.csv``, ``primary_summary.csv``, ``primary_convergence.csv`` and
``primary_attitude_error.csv`` of a run directory (written by
:func:`mcsweep.sweep.primary_runner.run_primary`): our Table 3 next to the paper's
(fractions and percentiles with their 68 % intervals, as Table 2;
:func:`~mcsweep.report.global_section.global_section`), the attitude error RMS
and its figure against time, the PCG iterations and their convergence figure, and the
knot interval.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..experiments.global_table import FRACTION_INTERVAL
from ..experiments.primary_table import table3_layout
from .document import FIG_DIR, Document
from .figures import plot_primary_attitude_error, plot_primary_convergence
from .global_section import global_section, section_config

__all__ = ["primary_section"]


def primary_section(doc: Document, run_dir: Path, prov: dict) -> None:
    """Add the Table 3 section to ``doc`` (see module notes)."""
    run_dir = Path(run_dir)
    cfg, pri, p = section_config(prov, "primary")
    summary = pd.read_csv(run_dir / "primary_summary.csv")
    global_section(
        doc, run_dir, prov, kind="primary",
        heading="One-year global solution with the attitude (paper Sect. 4.2, Table 3)",
        description=(
            f"{pri.get('class_size')} stars per class (paper: 5e5), the attitude from the same stars"
            + (f" and {pri.get('primary_sources')} extra stars G >= {pri.get('primary_g_min')} (not in the paper)"
               if pri.get("primary_sources") else " (as the paper)")
            + f"; {pri.get('mission_years')} year(s) from {pri.get('mission_start')} "
            f"(TCB), {100 * float(pri.get('dead_time_fraction', 0.2)):g} % dead time; one AL "
            f"{'and one AC measurement' if cfg.get('noise', {}).get('use_ac', True) else 'measurement (AL only)'} "
            f"per FoV transit; attitude solved as cubic splines with a {pri.get('knot_interval_hours')} h knot "
            f"interval; true attitude = law + {pri.get('attitude_amplitude_mas')} mas random rotation on a "
            f"{pri.get('attitude_timescale_hours')} h time scale. Errors after removing the frame rotation "
            f"and spin fitted with {'equal weights' if pri.get('frame_fit') == 'equal' else 'formal-precision weights'}; "
            "formal covariances from each star's own block with the attitude taken as known. Fractions "
            f"inside the P = {p:g} ellipse (Clopper-Pearson {100 * FRACTION_INTERVAL:g} % interval); errors = "
            f"{100 * p:g}th percentile [mas] (order-statistic {100 * FRACTION_INTERVAL:g} % interval). Each cell: "
            "ours [interval] (paper)."),
        table_file="table3.csv", layout=table3_layout,
        caption="Table 3, stars with {subset} field-of-view transits")
    cols = [c for c in ("prior", "iterations", "converged", "attitude_rms_uas", "residual_rms", "seconds",
                        "n_stars_solved", "n_measurements", "n_attitude_coefficients", "knot_interval_hours",
                        "dead_fraction") if c in summary]
    doc.table(summary[cols], "Global solutions: PCG iterations, attitude error RMS per axis (x, y, z) [uas] "
              "after the frame correction, RMS of the normalised residuals",
              {"residual_rms": ".4f", "seconds": ".1f", "dead_fraction": ".3f"})
    figdir = run_dir / FIG_DIR
    figdir.mkdir(exist_ok=True)
    plot_primary_convergence(pd.read_csv(run_dir / "primary_convergence.csv"), figdir / "primary_convergence.png")
    doc.figure(f"{FIG_DIR}/primary_convergence.png", "PCG convergence of each global solution: relative residual "
               "of the normal equations and the largest update of any unknown per iteration (stopping rule: "
               f"both below solver_rtol = {pri.get('solver_rtol')} and solver_update_tol_uas = "
               f"{pri.get('solver_update_tol_uas')})")
    att_file = run_dir / "primary_attitude_error.csv"
    if att_file.exists():
        plot_primary_attitude_error(pd.read_csv(att_file), figdir / "primary_attitude_error.png")
        doc.figure(f"{FIG_DIR}/primary_attitude_error.png", "Attitude error (estimated minus true, after removing "
                   "the fitted frame rotation and spin) per axis over the mission, at the centre of every knot "
                   "interval outside dead time; RMS over these epochs in the legend (the table's RMS is over the "
                   "measurement epochs)")
    factor_file = run_dir / "primary_factor.csv"
    if factor_file.exists():
        fac = pd.read_csv(factor_file)
        grid = ", ".join(f"{k:g}" for k in pri.get("factor_grid", []))
        doc.heading("Beyond the paper: the smallest factor k of sigma_F90 (primary solution)", level=3)
        doc.para(f"One global solution per k of the grid ({grid}; coarse: each k costs a solution); per cell the "
                 f"fraction inside the P = {p:g} ellipse against k and its crossing of P, linear in log k "
                 "(as sigma_F90, Sect. 3.3), with a bootstrap interval over the cell's stars "
                 f"({pri.get('factor_resamples')} resamples). The row 'all' is the largest cell value: the "
                 "smallest k that keeps P inside in every cell. Flags: below_grid = the smallest k already "
                 "reaches P (an upper limit); never_reached = above the grid. Curves: primary_factor_curves.csv.")
        doc.table(fac, "Smallest factor k per G class and subset", {"k_min": ".3g", "k_lo": ".3g", "k_hi": ".3g"})
