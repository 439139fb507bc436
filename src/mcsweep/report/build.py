"""Build a run directory's report from its result files (reads results, computes no cells).

For a sweep: ``f90_cells.csv`` (our sigma_F90 per cell next to the paper's formula),
``coefficients.csv`` (Eqs. 15-17: fitted, paper, difference), ``rms_dex.csv``, the
figures, and ``report.md`` / ``report.html``. Experiments with their own tables (e.g.
the secondary solution) add sections through :data:`SECTION_BUILDERS`.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Callable

import pandas as pd

from ..errors import UserInputError
from ..sweep.store import atomic_write_bytes
from . import figures
from .document import Document
from .fit import fit_all
from .primary_section import primary_section
from .secondary_section import secondary_section

__all__ = ["build_report", "SECTION_BUILDERS", "REQUIRED_RESULTS", "sweep_section", "provenance_section"]

FIG_DIR = "figures"


def _f90_table(cells: pd.DataFrame) -> pd.DataFrame:
    base = cells.drop_duplicates("cell_id")[["cell_id", "l_deg", "b_deg", "ra_deg", "dec_deg", "g_min",
                                             "g_max", "n_stars", "n_in_cone", "radius_deg", "n_groups",
                                             "sigma_f90_mas", "f90_flag"]]
    at = cells[cells["at_f90"]].pivot_table(index="cell_id", columns="case", values="fraction_inside")
    at.columns = [f"fraction_at_f90_{c}" for c in at.columns]
    return base.merge(at, left_on="cell_id", right_index=True, how="left").reset_index(drop=True)


def sweep_section(doc: Document, run_dir: Path, prov: dict) -> None:
    cells = pd.read_parquet(run_dir / "cells.parquet")
    f90 = _f90_table(cells)
    fit = fit_all(f90)
    for name, table in (("f90_cells.csv", fit.compared), ("coefficients.csv", fit.coefficients),
                        ("rms_dex.csv", fit.rms), ("eq14_terms.csv", fit.terms)):
        atomic_write_bytes(run_dir / name, table.to_csv(index=False).encode())
    figdir = run_dir / FIG_DIR
    figdir.mkdir(exist_ok=True)
    cfg = prov.get("config", {})
    p = float(cfg.get("confidence", 0.9))

    n_ok = int((f90["f90_flag"] == "ok").sum())
    flags = f90["f90_flag"].value_counts().to_dict()
    doc.heading("Optimum prior sigma_F90 over the sky (paper Sect. 3.4)")
    doc.para(f"{len(f90)} cells ({f90[['l_deg', 'b_deg']].drop_duplicates().shape[0]} directions x "
             f"{f90[['g_min', 'g_max']].drop_duplicates().shape[0]} G bins); sigma_F90 found in {n_ok} "
             f"(flags: {flags}). Confidence level P = {p:g}, R = {cfg.get('ratio_R')} /yr, "
             f"sigma_F90 fixed from the '{cfg.get('observations', {}).get('f90_case', 'two')}' case.")
    n_bins = int(fit.terms["s0"].notna().sum())
    if n_bins < 4:
        doc.para(f"Only {n_bins} G bins have an Eq. 14 fit: the polynomials of Eqs. 15-17 need at least "
                 "4 (s1 is cubic), so coefficients that cannot be determined are left empty.")
    doc.table(fit.coefficients, "Coefficients of Eqs. 15-17 (increasing powers of G): ours vs the paper's",
              {"fitted": ".5g", "paper": ".5g", "difference": "+.4g"})
    doc.table(fit.rms, "log10(sigma_F90 ours / paper formula) per G bin, cells with a valid sigma_F90",
              {"mean_diff_dex": "+.3f", "rms_diff_dex": ".3f"})
    doc.table(fit.terms[["g", "s0", "s1", "s2", "n_cells", "rms_dex"]],
              "Eq. 14 fitted per G bin (rms_dex: scatter of the cells about the fit)",
              {"s0": ".4f", "s1": ".4f", "s2": ".4f", "rms_dex": ".3f"})
    if fit.terms["s0"].notna().sum() > 0:
        for name, fn, cap in (
            ("fig4_latitude.png", figures.plot_fig4_latitude, "log sigma_F90 against |sin b| per G bin (Fig. 4 left)"),
            ("fig4_coefficients.png", figures.plot_fig4_coefficients, "s0, s1, s2 against G (Fig. 4 middle)"),
            ("fig4_magnitude.png", figures.plot_fig4_magnitude, "sigma_F90 against G at b = 0, 30, 90 deg (Fig. 4 right)"),
            ("sky_difference.png", figures.plot_sky_difference, "Sky map of log10(ours / paper)"),
        ):
            fn(fit, figdir / name)
            doc.figure(f"{FIG_DIR}/{name}", cap)
    worst = fit.compared[fit.compared["f90_flag"] == "ok"].reindex(
        fit.compared["diff_dex"].abs().sort_values(ascending=False).index).dropna(subset=["diff_dex"]).head(10)
    doc.table(worst[["l_deg", "b_deg", "g_min", "g_max", "n_stars", "radius_deg", "sigma_f90_mas",
                     "paper_sigma_f90_mas", "diff_dex"]],
              "Cells that disagree most with the paper's formula",
              {"l_deg": ".1f", "b_deg": ".1f", "radius_deg": ".2f", "sigma_f90_mas": ".3g",
               "paper_sigma_f90_mas": ".3g", "diff_dex": "+.2f"})
    frac_cols = [c for c in f90.columns if c.startswith("fraction_at_f90_")]
    if frac_cols:
        summary = f90[frac_cols].describe(percentiles=[0.1, 0.5, 0.9]).T[["count", "mean", "10%", "50%", "90%"]]
        summary.insert(0, "case", [c.removeprefix("fraction_at_f90_") for c in summary.index])
        doc.table(summary.reset_index(drop=True), "Fraction inside the P ellipse at each cell's sigma_F90, per case",
                  {"mean": ".3f", "10%": ".3f", "50%": ".3f", "90%": ".3f"})
    _showcase_section(doc, run_dir, figdir, p, cfg)


def _showcase_section(doc: Document, run_dir: Path, figdir: Path, p: float, cfg: dict) -> None:
    show = sorted((run_dir / "showcase").glob("cell_*.parquet")) if (run_dir / "showcase").exists() else []
    curves_files = [f for f in show if not f.stem.endswith("_scatter")]
    if not curves_files:
        return
    curves = pd.read_parquet(curves_files[0])
    scatter_file = curves_files[0].with_name(curves_files[0].stem + "_scatter.parquet")
    f90 = float(curves["sigma_f90_mas"].iloc[0])
    case = cfg.get("observations", {}).get("f90_case", "two")
    r = curves.iloc[0]
    doc.heading("Single direction: the paper's Table 1 beam (Figs. 1-3)")
    doc.para(f"(ra, dec) = ({r['ra_deg']:.1f}, {r['dec_deg']:.1f}) deg, (l, b) = ({r['l_deg']:.1f}, "
             f"{r['b_deg']:.1f}) deg, G = {r['g_min']:g}-{r['g_max']:g}: {int(r['n_stars'])} stars drawn of "
             f"{int(r['n_in_cone'])} in a {r['radius_deg']:.2f} deg beam (GUMS: 458 in 1 deg), "
             f"{int(r['n_groups'])} distinct transit groups. sigma_F90 = {f90:.3g} mas ({r['f90_flag']}).")
    at = curves[curves["at_f90"]][["case", "sigma_prior_mas", "fraction_inside", "p_error_mas",
                                   "median_semi_major_mas"]]
    doc.table(at, "Every case evaluated at the two-transit sigma_F90 (Fig. 3's vertical line)",
              {"sigma_prior_mas": ".3g", "fraction_inside": ".3f", "p_error_mas": ".3g",
               "median_semi_major_mas": ".3g"})
    figures.plot_showcase_curves(curves, case, f90, figdir / "fig1_curves.png", p)
    doc.figure(f"{FIG_DIR}/fig1_curves.png", "Actual errors and formal uncertainty against the prior (Fig. 1)")
    if scatter_file.exists():
        figures.plot_showcase_scatter(pd.read_parquet(scatter_file), figdir / "fig2_scatter.png", p)
        doc.figure(f"{FIG_DIR}/fig2_scatter.png", "Actual position errors and the confidence ellipse for a "
                   "tight prior, sigma_F90 and a loose prior (Fig. 2)")
    figures.plot_showcase_cases(curves, f90, figdir / "fig3_cases.png", p)
    doc.figure(f"{FIG_DIR}/fig3_cases.png", "1, 2, 2 diluted, 4 and 8 distinct transits (Fig. 3)")


def provenance_section(doc: Document, run_dir: Path, prov: dict) -> None:
    doc.heading("Provenance")
    doc.para(f"mcsweep {prov.get('mcsweep_version')}, git commit {prov.get('git_commit') or 'unknown'}, "
             f"Python {prov.get('python')}; config hash {prov.get('config_hash')}; seeds: {prov.get('seeds')}.")
    t = prov.get("timings_s", {})
    if t:
        doc.table(pd.DataFrame({"stage": list(t), "seconds": list(t.values())}), "Per-stage wall time",
                  {"seconds": ".1f"})
    man = prov.get("manifest", [])
    if man:
        doc.para(manifest_summary(man))
    doc.pre(json.dumps(prov.get("config", {}), indent=1, default=str))


def manifest_summary(manifest: list[dict]) -> str:
    """One sentence on the result files; the file-by-file list stays in provenance.json.

    The digest is SHA-256 over the sorted ``path:sha256`` lines, so two runs with the
    same results show the same digest whatever order their files were listed in.
    """
    lines = sorted(f"{m['path']}:{m['sha256']}" for m in manifest)
    digest = hashlib.sha256("\n".join(lines).encode()).hexdigest()
    total = sum(int(m["bytes"]) for m in manifest)
    return (f"Result files of the computation (before this report): {len(manifest)} files, {total / 1e6:.2f} MB in all, manifest digest "
            f"{digest[:16]} (SHA-256 over the sorted path:sha256 lines); each file's size and SHA-256 "
            "are listed under `manifest` in provenance.json.")


#: Extra sections by run kind; each takes (doc, run_dir, provenance dict).
SECTION_BUILDERS: dict[str, list[Callable]] = {"f90_sweep": [sweep_section], "secondary": [secondary_section],
                                               "primary": [primary_section]}
#: Result files each run kind's sections read: all must exist before anything is written.
REQUIRED_RESULTS: dict[str, tuple[str, ...]] = {
    "f90_sweep": ("cells.parquet",),
    "secondary": ("table2.csv", "no_prior.csv", "secondary_summary.csv"),
    "primary": ("table3.csv", "primary_summary.csv", "primary_convergence.csv"),
}


def build_report(run_dir) -> Path:
    """Write report.md and report.html in ``run_dir``; returns the Markdown path."""
    run_dir = Path(run_dir)
    pfile = run_dir / "provenance.json"
    if not pfile.exists():
        raise UserInputError(f"{run_dir} is not an mcsweep run directory (no provenance.json); "
                             "expected the directory of a finished run")
    try:
        prov = json.loads(pfile.read_text())
    except (OSError, ValueError) as exc:
        raise UserInputError(f"{pfile} is unreadable ({type(exc).__name__}: {exc}); expected the JSON "
                             "record written by mcsweep") from None
    kind = prov.get("kind", "f90_sweep")
    if kind not in SECTION_BUILDERS:
        raise UserInputError(f"{pfile}: unknown run kind {kind!r}; expected one of {', '.join(SECTION_BUILDERS)}")
    missing = [n for n in REQUIRED_RESULTS.get(kind, ()) if not (run_dir / n).is_file()]
    if missing:
        # An unfinished or interrupted run: provenance is written when the inputs are
        # accepted, the results only at the end. Nothing is written here.
        raise UserInputError(
            f"{run_dir} is an unfinished {kind} run: {', '.join(missing)} not written yet; expected a "
            f"finished run (run mcsweep again with hydra.run.dir={run_dir} and the same config to resume)")
    doc = Document(f"mcsweep report: {kind} ({run_dir.name})")
    for section in SECTION_BUILDERS.get(kind, []):
        section(doc, run_dir, prov)
    provenance_section(doc, run_dir, prov)
    md, _ = doc.write(run_dir)
    return md
