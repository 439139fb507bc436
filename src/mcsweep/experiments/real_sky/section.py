"""Report section of the real-sky validation: Hipparcos stars as truth.

Reads ``real_sky.csv``, ``real_sky_errors.csv`` and, where the run wrote it,
``real_sky_complete.csv`` (written by :func:`mcsweep.experiments.real_sky.runner.run_real_sky`).
In the order every global experiment's section follows (:mod:`mcsweep.experiments.global_solution.section`):
the headline (the fraction inside the P ellipse per |b| band for each prior, ours with its
Clopper-Pearson interval, in the case from which sigma_F90 is defined; the same per G bin
carried over to the complete sky, :mod:`mcsweep.experiments.real_sky.complete`; what
Hipparcos' own errors change),
the figure, then the setup and the tables, then the diagnostics (Hipparcos' parallax
errors against the prior).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from . import FIGURE  # noqa: E402
from ..global_solution.table import FRACTION_INTERVAL  # noqa: E402
from ...runtime.document import Document, plain  # noqa: E402
from ..global_solution.section import readable_table, section_config  # noqa: E402
from ..scanning_note import extrapolation_para  # noqa: E402

__all__ = ["real_sky_section", "plot_fraction_by_band"]


def _cell(r: pd.Series) -> str:
    if not np.isfinite(r["fraction_inside"]):
        return "–"
    return f"{100 * r['fraction_inside']:.1f} [{100 * r['fraction_lo']:.1f}-{100 * r['fraction_hi']:.1f}] %"


def plot_fraction_by_band(table: pd.DataFrame, case: str, p: float, path: Path) -> Path:
    """Fraction inside (68 % interval) per |b| band, one line per prior, truth = Hipparcos."""
    part = table[(table["truth"] == "hipparcos") & (table["case"] == case) & (table["g_bin"] == "all")]
    bands = [b for b in dict.fromkeys(part["b_band_deg"]) if b != "all"]
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    x = np.arange(len(bands))
    for k, prior in enumerate(dict.fromkeys(part["prior"])):
        r = part[part["prior"] == prior].set_index("b_band_deg").loc[bands]
        f = 100 * r["fraction_inside"].to_numpy(float)
        err = np.vstack([f - 100 * r["fraction_lo"].to_numpy(float), 100 * r["fraction_hi"].to_numpy(float) - f])
        ax.errorbar(x + 0.08 * (k - 0.5), f, yerr=err, marker="o", capsize=3, label=f"prior: {prior}")
    ax.axhline(100 * p, color="k", lw=0.8, ls="--", label=f"P = {p:g}")
    ax.set_xticks(x, [f"|b| {b} deg" for b in bands])
    ax.set_ylabel(f"inside the {100 * p:g} % ellipse [%]")
    ax.set_title(f"Hipparcos stars as truth, case '{case}'")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _carried(r: pd.Series) -> str:
    f, e = r["fraction_complete_sky"], r["fraction_complete_sky_sigma"]
    return "–" if not np.isfinite(f) else f"{100 * f:.1f} +- {100 * e:.1f}"


def real_sky_section(doc: Document, run_dir: Path, prov: dict) -> None:
    """Add the real-sky section to ``doc`` (module notes)."""
    run_dir = Path(run_dir)
    cfg, sec, p = section_config(prov, "real_sky")
    table = pd.read_csv(run_dir / "real_sky.csv", dtype={"b_band_deg": str, "g_bin": str})
    errors = pd.read_csv(run_dir / "real_sky_errors.csv", dtype={"b_band_deg": str, "g_bin": str})
    cases = list(dict.fromkeys(table["case"]))
    f90_case = cfg.get("observations", {}).get("f90_case", "two")
    case = f90_case if f90_case in cases else cases[0]
    priors = list(dict.fromkeys(table["prior"]))

    doc.heading("Real-sky validation: Hipparcos stars as truth")
    doc.para(f"Fraction of actual position errors inside the {100 * p:g} % confidence ellipse, ours "
             f"[{100 * FRACTION_INTERVAL:g} % Clopper-Pearson interval], case '{case}' (the case that defines "
             "sigma_F90, Sect. 3.3), all G, per |b| band:")
    doc.bullets(_headline_items(run_dir, table, errors, case, cases, priors))
    # Where every global section says it (the real-sky run is one, run_global records the note).
    extrapolation_para(doc, prov)
    fig = plot_fraction_by_band(table, case, p, run_dir / FIGURE)
    doc.figure(fig.name, f"Fraction inside the {100 * p:g} % ellipse per |b| band and prior, case '{case}', "
                         f"with {100 * FRACTION_INTERVAL:g} % Clopper-Pearson intervals.")

    _setup_and_tables(doc, prov, table, cases, priors, p)

    doc.heading("Diagnostics", level=3)
    readable_table(doc, errors, "Hipparcos' own parallax errors against the prior, per |b| band and G bin",
                   {c: ".3g" for c in errors.columns if c not in ("b_band_deg", "g_bin", "n_stars")})
    doc.para("Hipparcos' errors are the truth's noise: the real stars' parallaxes and proper motions differ from "
             "the catalogue's by about e_Plx, e_pmRA, e_pmDE. Where e_Plx is small against sigma_F90 the prior's "
             "bias, and so the fraction inside, hardly depends on which of the two the truth is; the rows "
             "'perturbed' of real_sky.csv solve the same stars with the same measurement noise and the truth "
             "drawn around the catalogue's values, and the headline gives the change.")



def _headline_items(run_dir: Path, table: pd.DataFrame, errors: pd.DataFrame, case: str, cases: list,
                    priors: list) -> list[str]:
    """The headline's bullets: the fraction per |b| band and prior in the F90 case, carried
    over to the complete sky, what Hipparcos' errors change, and how large they are."""
    base = table[(table["truth"] == "hipparcos") & (table["g_bin"] == "all")]
    items = []
    for prior in priors:
        r = base[(base["prior"] == prior) & (base["case"] == case)].set_index("b_band_deg")
        items.append(f"prior '{prior}': all sky {_cell(r.loc['all'])}; "
                     + "; ".join(f"|b| {b} deg {_cell(r.loc[b])}" for b in r.index if b != "all"))
    complete_file = run_dir / "real_sky_complete.csv"
    complete = (pd.read_csv(complete_file, dtype={"b_band_deg": str, "g_bin": str}) if complete_file.exists()
                else None)
    if complete is not None:
        for prior in priors:
            part = complete[(complete["prior"] == prior) & (complete["case"] == case)]
            if part.empty:
                continue
            items.append(f"Carried over to the complete sky (Gaia DR3's stars by BP - RP, prior '{prior}'), "
                         "per |b| band, G bins " + " / ".join(dict.fromkeys(part["g_bin"])) + ": "
                         + "; ".join(f"|b| {b} deg " + " / ".join(_carried(r) for _, r in band.iterrows())
                                     for b, band in part.groupby("b_band_deg", sort=False))
                         + " % (Hipparcos holds " + ", ".join(f"{100 * v:.0f}" for v in part["hipparcos_completeness"])
                         + " % of those cells' stars).")
    pert = table[(table["truth"] == "perturbed") & (table["g_bin"] == "all") & (table["b_band_deg"] == "all")]
    for prior in priors:
        a = base[(base["prior"] == prior) & (base["b_band_deg"] == "all")].set_index("case")["fraction_inside"]
        b = pert[pert["prior"] == prior].set_index("case")["fraction_inside"]
        d = 100 * (b - a).reindex(cases)
        items.append(f"Truth perturbed by Hipparcos' own errors (prior '{prior}'): the all-sky fraction changes by "
                     + ", ".join(f"{c} {v:+.1f}" for c, v in d.items()) + " points.")
    ratio_cols = [c for c in errors.columns if c.startswith("error_over_sigma_")]
    if ratio_cols:
        r = errors[ratio_cols[0]].to_numpy(float)
        items.append(f"Hipparcos' median parallax error is {plain(np.nanmin(r), '.2g')}-{plain(np.nanmax(r), '.2g')} "
                     f"x the median sigma_F90 of the paper's prior over the |b| band x G bin cells "
                     f"(median e_Plx {plain(np.nanmedian(errors['median_parallax_error_mas']), '.2g')} mas).")
    return items


def _setup_and_tables(doc: Document, prov: dict, table: pd.DataFrame, cases: list, priors: list, p: float) -> None:
    """What was solved how, the reference epoch, and one table per prior."""
    cfg, sec, _ = section_config(prov, "real_sky")
    doc.heading("Setup and tables", level=3)
    obs = cfg.get("observations", {})
    doc.para(f"Hipparcos 2 stars (van Leeuwen 2007, CDS I/311) with {plain(sec.get('g_min'))} <= G < "
             f"{plain(sec.get('g_max'))} (G from Hp, B-V and V-I: Bessell 2000, Table 2, and Jordi et al. 2010, "
             f"Table 3), max_stars = {plain(sec.get('max_stars'))} (0 = all); each star observed with the "
             f"`{cfg.get('scanning', {}).get('name')}` scanning law's transits at its own position between "
             f"{obs.get('start')} and {obs.get('end')} (TCB), in the observation cases {', '.join(cases)}; truth: "
             "position zero at the reference epoch, the Hipparcos parallax and proper motion. Priors: "
             f"{', '.join(priors)} (f90_formula = `{sec.get('f90_formula')}`) x {plain(sec.get('factor'))}, "
             f"R = {plain(cfg.get('ratio_R'))} /yr. Errors are the {100 * p:g}th percentile of |estimated - true "
             "position|.")
    epoch = prov.get("derived", {}).get("real_sky", {}).get("reference_epoch", {})
    doc.para(f"Reference epoch: {epoch.get('text', 'not recorded')}.")
    for prior in priors:
        part = table[(table["truth"] == "hipparcos") & (table["prior"] == prior)]
        rows = []
        for c in cases:
            for b in dict.fromkeys(part["b_band_deg"]):
                row = {"case": c, "abs(b) band [deg]": b}
                for g in dict.fromkeys(part["g_bin"]):
                    r = part[(part["case"] == c) & (part["b_band_deg"] == b) & (part["g_bin"] == g)].iloc[0]
                    row[f"G {g}"] = _cell(r) + f" / {plain(r['p_error_mas'], '.3g')} mas"
                rows.append(row)
        doc.table(pd.DataFrame(rows), f"Prior '{prior}': fraction inside [interval] / p{100 * p:g} error")
