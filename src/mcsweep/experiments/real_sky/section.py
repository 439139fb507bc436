"""Report section of the real-sky validation: Hipparcos stars as truth.

Reads ``real_sky.csv``, ``real_sky_errors.csv`` and, where the run wrote it,
``real_sky_complete.csv`` (written by :func:`mcsweep.experiments.real_sky.runner.run_real_sky`).
In the order every global experiment's section follows (:mod:`mcsweep.experiments.global_solution.section`):
the headline (the fraction inside the P ellipse per |b| band for each prior, ours with its
Clopper-Pearson interval, in the case from which sigma_F90 is defined; the same per G bin
carried over to the complete sky, :mod:`mcsweep.experiments.real_sky.complete`; what
Hipparcos' own errors change),
the figure, then the setup and the tables, then the diagnostics (Hipparcos' parallax
errors against the prior). Where ``real_sky.csv`` has BP-RP bins (``colour_bin``), a table
and a figure per |b| band x BP-RP bin for every prior (the F90 case, G = 6-8) follow the
first figure, with a headline bullet per prior on how many of those cells lie in the
88-92 % band and, for each colour prior, its P-th percentile error against the
colour-blind zero-mean prior's.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from . import COLOUR_FIGURE, FIGURE  # noqa: E402
from .experiment import COLOUR_BINS, colour_cell, colour_target_g  # noqa: E402
from ..global_solution.table import FRACTION_INTERVAL  # noqa: E402
from ...runtime.document import Document, plain  # noqa: E402
from ..global_solution.section import readable_table, section_config  # noqa: E402
from ..scanning_note import extrapolation_para  # noqa: E402

__all__ = ["real_sky_section", "plot_fraction_by_band", "plot_fraction_by_colour", "TARGET_BAND"]

#: The band of fractions inside in which the real-sky validation counts a prior as honest
#: (docs/experiments/real_sky.md): P = 0.9 +- 2 points.
TARGET_BAND = (0.88, 0.92)


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
    full = pd.read_csv(run_dir / "real_sky.csv", dtype={"b_band_deg": str, "g_bin": str, "colour_bin": str})
    # tables written before the BP-RP bins have only the rows of every colour
    table = full[full["colour_bin"] == "all"] if "colour_bin" in full else full
    errors = pd.read_csv(run_dir / "real_sky_errors.csv", dtype={"b_band_deg": str, "g_bin": str})
    cases = list(dict.fromkeys(table["case"]))
    f90_case = cfg.get("observations", {}).get("f90_case", "two")
    case = f90_case if f90_case in cases else cases[0]
    priors = list(dict.fromkeys(table["prior"]))

    doc.heading("Real-sky validation: Hipparcos stars as truth")
    doc.para(f"Fraction of actual position errors inside the {100 * p:g} % confidence ellipse, ours "
             f"[{100 * FRACTION_INTERVAL:g} % Clopper-Pearson interval], case '{case}' (the case that defines "
             "sigma_F90, Sect. 3.3), all G, per |b| band:")
    colour = _colour_part(full, case)
    doc.bullets(_headline_items(run_dir, table, errors, case, cases, priors) + _colour_items(colour, p))
    # Where every global section says it (the real-sky run is one, run_global records the note).
    extrapolation_para(doc, prov)
    fig = plot_fraction_by_band(table, case, p, run_dir / FIGURE)
    doc.figure(fig.name, f"Fraction inside the {100 * p:g} % ellipse per |b| band and prior, case '{case}', "
                         f"with {100 * FRACTION_INTERVAL:g} % Clopper-Pearson intervals.")
    if colour is not None:
        _colour_table_and_figure(doc, colour, case, p, run_dir)

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
             f"{', '.join(priors)} (f90_formula = `{sec.get('f90_formula')}`"
             + (f"; colour_priors = {', '.join(f'`{d}`' for d in sec['colour_priors'])}, queried with each star's "
                "Gaia DR3 BP-RP and, for a run with a mean, centred on it" if sec.get("colour_priors") else "")
             + f") x {plain(sec.get('factor'))}, "
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


# --------------------------------------------------------------------------- BP-RP bins
def _colour_part(full: pd.DataFrame, case: str) -> pd.DataFrame | None:
    """The rows per |b| band x BP-RP bin of the F90 case, truth = Hipparcos, G bin
    :func:`~mcsweep.experiments.real_sky.experiment.colour_target_g`; None without BP-RP bins."""
    if "colour_bin" not in full or not ((full["colour_bin"] != "all") & (full["n_valid"] > 0)).any():
        return None
    part = full[(full["truth"] == "hipparcos") & (full["case"] == case)]
    return part[part["g_bin"] == colour_target_g(part)]


def _colour_names(colour: pd.DataFrame) -> list[str]:
    return [c for c, _, _ in COLOUR_BINS if (colour["colour_bin"] == c).any()]


def _colour_items(colour: pd.DataFrame | None, p: float) -> list[str]:
    """Per prior: how many band x BP-RP cells lie in :data:`TARGET_BAND` and their range;
    for each colour prior (with or without a mean), its P-th percentile error over the
    colour-blind zero-mean prior's ('fitted', where it was solved)."""
    if colour is None:
        return []
    lo, hi = TARGET_BAND
    cells = colour[(colour["b_band_deg"] != "all") & (colour["colour_bin"] != "all") & (colour["n_valid"] > 0)]
    gname = colour["g_bin"].iloc[0]
    items = []
    for prior, part in cells.groupby("prior", sort=False):
        f = part["fraction_inside"].to_numpy(float)
        items.append(f"Per |b| band x BP-RP bin (G {gname}), prior '{prior}': {int(np.sum((f >= lo) & (f <= hi)))} of "
                     f"{f.size} cells at {100 * lo:g}-{100 * hi:g} % inside (range {plain(100 * np.nanmin(f), '.1f')}-"
                     f"{plain(100 * np.nanmax(f), '.1f')} %).")
    ref = colour[colour["prior"] == "fitted"].set_index(["b_band_deg", "colour_bin"])["p_error_mas"]
    if ref.empty:
        return items
    for prior in dict.fromkeys(colour["prior"]):
        if prior in ("paper", "fitted"):
            continue
        mine = colour[colour["prior"] == prior].set_index(["b_band_deg", "colour_bin"])["p_error_mas"]
        ratio = (mine / ref).dropna()
        per_cell = ratio[[b != "all" and c != "all" for b, c in ratio.index]]
        if per_cell.empty or ("all", "all") not in ratio.index:
            continue
        items.append(f"Prior '{prior}' against the colour-blind zero-mean prior 'fitted' (G {gname}): the "
                     f"p{100 * p:g} position error is {plain(ratio[('all', 'all')], '.2f')} x over all stars and "
                     f"{plain(per_cell.min(), '.2f')}-{plain(per_cell.max(), '.2f')} x per |b| band x BP-RP bin.")
    return items


def _colour_table_and_figure(doc: Document, colour: pd.DataFrame, case: str, p: float, run_dir: Path) -> None:
    gname = colour["g_bin"].iloc[0]
    cnames = _colour_names(colour) + ["all"]
    rows = []
    for prior in dict.fromkeys(colour["prior"]):
        for band in dict.fromkeys(colour["b_band_deg"]):
            cell = colour[(colour["prior"] == prior) & (colour["b_band_deg"] == band)].set_index("colour_bin")
            rows.append({"prior": prior, "abs(b) band [deg]": band,
                         **{f"BP-RP {c}": colour_cell(cell.loc[c]) for c in cnames}})
    edges = "; ".join(f"{c}: {'' if np.isinf(lo) else f'{lo:g} <= '}BP-RP{'' if np.isinf(hi) else f' < {hi:g}'}"
                      for c, lo, hi in COLOUR_BINS)
    doc.table(pd.DataFrame(rows), f"Per |b| band x Gaia DR3 BP-RP bin ({edges}), case '{case}', G {gname}: fraction "
                                  f"inside the {100 * p:g} % ellipse [%, {100 * FRACTION_INTERVAL:g} % interval] / "
                                  f"p{100 * p:g} position error [mas] (n = stars solved)")
    fig = plot_fraction_by_colour(colour, case, p, run_dir / COLOUR_FIGURE)
    doc.figure(fig.name, f"Fraction inside the {100 * p:g} % ellipse per |b| band x BP-RP bin and prior, case "
                         f"'{case}', G {gname}, with {100 * FRACTION_INTERVAL:g} % Clopper-Pearson intervals; "
                         f"shaded: {100 * TARGET_BAND[0]:g}-{100 * TARGET_BAND[1]:g} %.")


def plot_fraction_by_colour(colour: pd.DataFrame, case: str, p: float, path: Path) -> Path:
    """Fraction inside (68 % interval) per |b| band x BP-RP bin, one series per prior,
    :data:`TARGET_BAND` shaded; ``colour``: rows of one case and G bin, truth = Hipparcos."""
    bands = [b for b in dict.fromkeys(colour["b_band_deg"]) if b != "all"]
    cnames = _colour_names(colour)
    cells = [(b, c) for b in bands for c in cnames]
    priors = list(dict.fromkeys(colour["prior"]))
    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    ax.axhspan(100 * TARGET_BAND[0], 100 * TARGET_BAND[1], color="0.85", zorder=0,
               label=f"{100 * TARGET_BAND[0]:g}-{100 * TARGET_BAND[1]:g} %")
    x = np.arange(len(cells))
    width = 0.7 / max(len(priors), 1)
    for k, prior in enumerate(priors):
        r = colour[colour["prior"] == prior].set_index(["b_band_deg", "colour_bin"]).reindex(cells)
        f = 100 * r["fraction_inside"].to_numpy(float)
        err = np.vstack([f - 100 * r["fraction_lo"].to_numpy(float), 100 * r["fraction_hi"].to_numpy(float) - f])
        ax.errorbar(x + width * (k - (len(priors) - 1) / 2), f, yerr=err, marker="o", ls="none", capsize=2,
                    label=f"prior: {prior}")
    for i in range(1, len(bands)):
        ax.axvline(i * len(cnames) - 0.5, color="0.6", lw=0.6)
    ax.set_xticks(x, [f"{c}\n|b| {b}" for b, c in cells], fontsize=7)
    ax.set_ylabel(f"inside the {100 * p:g} % ellipse [%]")
    ax.set_title(f"Hipparcos stars by Gaia BP-RP, case '{case}', G {colour['g_bin'].iloc[0]}", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
