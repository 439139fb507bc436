"""Report section of the real-epochs experiment: random subsets of real Gaia DR4 transits.

Reads ``real_epochs.csv`` and ``real_epochs_sources.csv`` (written by
:func:`mcsweep.experiments.real_epochs.runner.run`) and the sample's description in provenance
(``derived.real_epochs``). In the order every section follows: the headline (what the sample
is, stated plainly; the fractions inside the P ellipse with the paper's sigma_F90 for held
and not-held stars, with their intervals; what differs from the paper's Table 2 and the
diagnostic that shows why), the figure, then the setup and the tables, then the sources.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from . import FIGURE, SOURCES_TABLE, TABLE  # noqa: E402
from ...prior import G_FIT_MAX, G_FIT_MIN  # noqa: E402
from ...runtime.document import Document, plain, save_png  # noqa: E402
from ..global_solution.priors import prior_label  # noqa: E402
from ..global_solution.section import readable_table, section_config  # noqa: E402
from ..global_solution.table import FRACTION_INTERVAL, PAPER_CONFIDENCE  # noqa: E402

__all__ = ["real_epochs_section", "plot_fraction_by_k", "label"]

#: How the section names the classes of stars.
_CLASS_TITLES = {"held": "held by the prior", "not_held": "not held (nearby or fast stars)", "all": "all"}
#: Above this transit-level unit-weight variance a source's CCD errors are shared within a
#: transit (the variance's sampling scatter with ~50-180 transits is ~0.1-0.2 for
#: independent errors), which the headline names as a cause.
_SHARED_ERRORS_VARIANCE = 1.5


def label(prior: str) -> str:
    """The paper's row label ('none' is Table 2's position-only row)."""
    return "none (2 parameters)" if prior == "none" else "fitted sigma_F90" if prior == "fitted" else prior_label(prior)


def _pct(r: pd.Series) -> str:
    if not np.isfinite(r["fraction_inside"]):
        return "–"
    return f"{100 * r['fraction_inside']:.1f} [{100 * r['fraction_lo']:.1f}-{100 * r['fraction_hi']:.1f}] %"


def _boot(r: pd.Series) -> str:
    lo, hi = r["fraction_boot_lo"], r["fraction_boot_hi"]
    return "–" if not np.isfinite(lo) else f"{100 * lo:.0f}-{100 * hi:.0f} %"


def _err(r: pd.Series) -> str:
    e, lo, hi = r["p_error_mas"], r["p_error_boot_lo_mas"], r["p_error_boot_hi_mas"]
    if not np.isfinite(e):
        return "–"
    return f"{e:.3g} [{lo:.3g}-{hi:.3g}]" if np.isfinite(lo) else f"{e:.3g}"


def plot_fraction_by_k(table: pd.DataFrame, p: float, path: Path) -> Path:
    """Fraction inside (Clopper-Pearson interval) against k, one line per prior; one panel
    per class (rows: held, not held) and unit (columns), the P line dashed."""
    units = list(dict.fromkeys(table["unit"]))
    classes = [c for c in ("held", "not_held") if c in set(table["star_class"])]
    priors = list(dict.fromkeys(table["prior"]))
    fig, axes = plt.subplots(len(classes), len(units), figsize=(4.2 * len(units), 3.2 * len(classes)),
                             sharey=True, squeeze=False)
    for i, cls in enumerate(classes):
        for j, unit in enumerate(units):
            ax = axes[i, j]
            part = table[(table["star_class"] == cls) & (table["unit"] == unit)]
            for n, prior in enumerate(priors):
                r = part[part["prior"] == prior].sort_values("k")
                k = r["k"].to_numpy(float) + 0.06 * (n - (len(priors) - 1) / 2)
                f = 100 * r["fraction_inside"].to_numpy(float)
                err = np.vstack([f - 100 * r["fraction_lo"].to_numpy(float),
                                 100 * r["fraction_hi"].to_numpy(float) - f])
                ax.errorbar(k, f, yerr=err, marker="o", ms=4, capsize=2, label=label(prior))
            ax.axhline(100 * p, color="k", lw=0.8, ls="--", label=f"P = {p:g}")
            n_src = int(part["n_sources"].max()) if len(part) else 0
            ax.set_title(f"{_CLASS_TITLES[cls]} ({n_src} sources), k {unit}", fontsize=9)
            ax.set_xlabel(f"k [{unit}]")
            ax.set_xticks(sorted(set(part["k"])))
            if j == 0:
                ax.set_ylabel(f"inside the {100 * p:g} % ellipse [%]")
            ax.set_ylim(-3, 103)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    return save_png(fig, path, trim=True)


def _sample_para(doc: Document, derived: dict, sources: pd.DataFrame) -> None:
    d = derived
    g, tr, vi, span = d.get("g_range_mag"), d.get("transit_range"), d.get("visit_range"), d.get("time_span_range_yr")
    n, n_not, n_held = d.get("n_sources"), d.get("n_not_held"), d.get("n_held")
    text = (f"The sample: {plain(n)} sources of `{d.get('epoch_file')}` with `{d.get('sources_file')}`, G "
            f"{plain(g[0], '.1f')}-{plain(g[1], '.1f')}, {plain(tr[0])}-{plain(tr[1])} FoV transits in "
            f"{plain(vi[0])}-{plain(vi[1])} visits over {plain(span[0], '.1f')}-{plain(span[1], '.1f')} yr each. "
            f"{plain(n_not)} of the {plain(n)} are nearby or fast stars the prior cannot hold (by their all-transit "
            f"solution |parallax| > {plain(d.get('hold_limit_sigma'))} sigma_F90 or |mu| > "
            f"{plain(d.get('hold_limit_sigma'))} R sigma_F90) and {plain(n_held)} are held")
    if d.get("n_without_truth"):
        text += f"; {plain(d['n_without_truth'])} have no determined all-transit solution and are left out"
    text += "."
    if d.get("sample"):
        from .inputs import SAMPLE_NOTE

        text += (f" These are {SAMPLE_NOTE}. {plain(n)} sources are a handful: every number below describes "
                 "these sources, not Gaia's sky, and the held class rests on "
                 f"{plain(n_held)} source{'s' * (n_held != 1)}.")
    bright = sources.drop_duplicates("source_id")
    bright = bright[bright["phot_g_mean_mag"] < G_FIT_MIN]
    if len(bright):
        text += (f" {len(bright)} source{'s are' if len(bright) != 1 else ' is'} brighter than G = 6, where the "
                 f"paper's Eqs. 15-17 are extrapolated (fitted at G = {G_FIT_MIN:g}-{G_FIT_MAX:g}; Sect. 3.4 suggests "
                 "Hipparcos/Tycho priors there).")
    doc.para(text)


def _headline_items(table: pd.DataFrame, sources: pd.DataFrame, p: float) -> list[str]:
    items = []
    for cls in ("held", "not_held"):
        part = table[table["star_class"] == cls]
        if part.empty or part["n_sources"].max() == 0:
            continue
        configured = [q for q in dict.fromkeys(part["prior"]) if q != "none"]
        # the paper's sigma_F90 where it was solved (else the first prior), and position only
        for prior in (["F90"] if "F90" in configured else configured[:1]) + ["none"]:
            rows = part[part["prior"] == prior]
            compared = cls == "held" and prior == "F90" and abs(p - PAPER_CONFIDENCE) < 1e-12
            cells = "; ".join(f"{r['k']} {r['unit']} {_pct(r)}" + (f" (bootstrap {_boot(r)})" if compared else "")
                              for _, r in rows.iterrows())
            items.append(f"{_CLASS_TITLES[cls].capitalize()}, prior {label(prior)}: {cells} inside the "
                         f"{100 * p:g} % ellipse" + (" (the paper's Table 2, <= 4 transits, sigma_F90: 90.1-91.4 % "
                                                      "on simulated GUMS stars)." if compared else "."))
    loose = table[(table["star_class"] == "all") & (table["prior"] == "1000mas")]
    if len(loose) and abs(p - PAPER_CONFIDENCE) < 1e-12:  # the paper's fractions are those of P = 0.9
        r = loose.loc[loose["k"].idxmax()]
        items.append(f"With the loose 1000 mas prior (Table 2's row; the position then follows the measurements), all "
                     f"sources at {r['k']} {r['unit']}: {_pct(r)} inside (bootstrap over the sources {_boot(r)}; the "
                     "paper's Table 2: 89.5-90.0 % with > 4 transits, simulated Gaussian errors).")
    uwv = sources.drop_duplicates("source_id")
    shared = uwv[uwv["transit_unit_weight_variance"] > _SHARED_ERRORS_VARIANCE]
    if len(shared):
        items.append(f"{len(shared)} of the {len(uwv)} sources have errors shared by a transit's CCDs: the mean "
                     "square of their per-transit mean residual over its formal error is "
                     + ", ".join(f"{plain(v, '.1f')}" for v in shared["transit_unit_weight_variance"])
                     + f" (source_id {', '.join(str(s) for s in shared['source_id'])}; 1 for independent CCDs), so a "
                     "few transits' formal ellipse is too small by about its square root whatever the prior: the "
                     "paper's simulations have independent Gaussian errors and no such term.")
    return items


def real_epochs_section(doc: Document, run_dir: Path, prov: dict) -> None:
    """Add the real-epochs section to ``doc`` (module notes)."""
    run_dir = Path(run_dir)
    cfg, sec, p = section_config(prov, "real_epochs")
    derived = prov.get("derived", {}).get("real_epochs", {})
    table = pd.read_csv(run_dir / TABLE)
    sources = pd.read_csv(run_dir / SOURCES_TABLE)
    doc.heading("Real Gaia DR4 epoch astrometry: random subsets of real transits")
    _sample_para(doc, derived, sources)
    doc.para(f"Fraction of the subsets' actual position errors inside their {100 * p:g} % confidence ellipse "
             f"[{100 * FRACTION_INTERVAL:g} % Clopper-Pearson interval over the draws], per class of stars, with "
             "the paper's sigma_F90 and position only:")
    doc.bullets(_headline_items(table, sources, p))
    fig = plot_fraction_by_k(table, p, run_dir / FIGURE)
    doc.figure(fig.name, f"Fraction inside the {100 * p:g} % ellipse against the subset size k, per prior, for "
                         f"held and not-held stars, with {100 * FRACTION_INTERVAL:g} % Clopper-Pearson intervals; "
                         "dashed: P. Nothing was tuned towards P.")

    doc.heading("Setup and tables", level=3)
    doc.para(f"Truth: each source's five-parameter solution from all its transits without prior, at "
             f"{derived.get('truth_epoch', 'J2017.5')} (AGIS's weights: each CCD's error and the source's excess "
             "noise). Subsets: "
             f"{plain(sec.get('draws'))} random draws per source of k FoV transits (k = {plain(sec.get('transits'))}) "
             f"and of all transits of k visits (k = {plain(sec.get('visits'))}; a visit: consecutive transits less "
             "than 1 day and 5 deg apart, Table 1's distinct transits), each solved at its own mean epoch "
             "(Sect. 2.1) with the priors of Eq. 18 (zero-centred, sigma_mu = R sigma_plx, "
             f"R = {plain(cfg.get('ratio_R'))} /yr): {', '.join(label(q) for q in dict.fromkeys(table['prior']))}; "
             "sigma_F90 from Eqs. 14-17 at each source's l, b, G"
             + (f"; fitted: the sweep `{sec.get('fitted_prior')}`" if sec.get("fitted_prior") else "")
             + ". The truth's position at that epoch is its J2017.5 position plus its proper motion times the epoch "
             "difference (the local plane is linear in time). Error = subset minus truth; a subset without a "
             "determined position (e.g. transits scanning one direction) has no ellipse and is left out of the "
             f"fraction (n valid). Errors: the {100 * p:g}th percentile of |error| [mas]; intervals in brackets "
             f"are the central {100 * FRACTION_INTERVAL:g} % of a bootstrap over the sources (the draws of one source "
             "share its truth and geometry, so the Clopper-Pearson interval, which treats them as independent, is "
             "too narrow).")
    for cls in ("held", "not_held", "all"):
        part = table[table["star_class"] == cls]
        if part.empty:
            continue
        rows = []
        for prior in dict.fromkeys(part["prior"]):
            row = {"prior": label(prior)}
            for _, r in part[part["prior"] == prior].iterrows():
                row[f"k={r['k']} {r['unit']}"] = f"{_pct(r)} (boot {_boot(r)}) / {_err(r)} mas"
            rows.append(row)
        doc.table(pd.DataFrame(rows), f"Stars {_CLASS_TITLES[cls]} ({int(part['n_sources'].max())} sources): "
                                      f"fraction inside the {100 * p:g} % ellipse [interval] (bootstrap over sources) "
                                      f"/ p{100 * p:g} position error [bootstrap interval]")

    doc.heading("Sources", level=3)
    one = sources.drop_duplicates("source_id")
    cols = ["source_id", "phot_g_mean_mag", "l_deg", "b_deg", "n_transits", "n_visits", "truth_parallax_mas",
            "sigma_f90_mas", "parallax_over_sigma_f90", "pm_over_sigma_pm", "transit_unit_weight_variance",
            "star_class"]
    readable_table(doc, one[cols], "Each source: its truth against the paper's prior and the transit-level unit-weight "
                                   "variance of its measurements (1 for independent CCD errors)",
                   {c: ".3g" for c in cols if c not in ("source_id", "n_transits", "n_visits", "star_class")})
    f90 = sources[(sources["prior"] == "F90") & (sources["n_valid"] > 0)] if "F90" in set(sources["prior"]) else None
    if f90 is not None and len(f90):
        wide = f90.assign(cell=[f"k={k} {u}" for u, k in zip(f90["unit"], f90["k"])]).pivot(
            index="source_id", columns="cell", values="fraction_inside")
        wide = wide[list(dict.fromkeys(f"k={k} {u}" for u, k in zip(f90["unit"], f90["k"])))]
        readable_table(doc, (100 * wide).reset_index(), "Fraction inside [%] per source, prior sigma_F90",
                       {c: ".0f" for c in wide.columns})
