"""The F90 sweep's part of the report: the headline (Fig. 4 analogues, key numbers, what
differs from the paper and why, the sky maps), the long tables, then the Table 1 beam
(Figs. 1-3). Reads what the sweep wrote when it aggregated its cells
(:func:`mcsweep.experiments.f90_sweep.runner.run_sweep`, fit in
:mod:`mcsweep.experiments.f90_sweep.fit`): ``f90_cells.csv`` (our sigma_F90 per cell next to
the paper's formula), ``coefficients.csv`` (Eqs. 15-17: fitted, paper, difference),
``rms_dex.csv``, ``eq14_terms.csv`` (Eq. 14 per G bin) and ``prior_maps.fits`` (HEALPix maps
of the fitted prior, :mod:`mcsweep.prior.maps`); computes nothing. A run with a colour axis
(``prior_model=colour`` or ``colour_mean``) also gets the subsection of
:mod:`mcsweep.experiments.f90_sweep.colour_section`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import UserInputError
from ...prior import Prior
from ...prior.maps import MAPS_FILE
from ...runtime.document import FIG_DIR, Document, counts_text, plain
from ..scanning_note import extrapolation_para
from . import figures
from .colour_section import colour_section
from .fit import PAPER_COEFFICIENTS, evaluate_formula, read_fit

__all__ = ["sweep_section"]


#: Michalik et al. (2015), Table 1: the star (alpha, delta) = (157.5, 0) deg and the UTC
#: time of the first transit of each of its 8 distinct transit groups "#" (pre-launch
#: nominal scanning law; the table gives 0.1 h).
TABLE1_RA_DEC_DEG = (157.5, 0.0)
TABLE1_GROUP_STARTS_UTC = ("2014-10-30T17:00", "2014-11-20T17:00", "2014-12-19T16:36", "2015-04-29T05:12",
                           "2015-05-23T18:54", "2015-06-21T04:54", "2015-11-09T06:06", "2015-12-29T11:48")


def sweep_section(doc: Document, run_dir: Path, prov: dict) -> None:
    """The F90 sweep: the headline (Fig. 4 analogues, key numbers, what differs and why,
    the sky maps) first, then the long tables, then the Table 1 beam (Figs. 1-3).

    Reads the fit the sweep wrote (:func:`mcsweep.experiments.f90_sweep.fit.read_fit`); the
    per-cell table ``f90_cells.csv`` holds every column of the cells it was fitted to.
    """
    fit = read_fit(run_dir)
    f90 = fit.compared
    figdir = run_dir / FIG_DIR
    figdir.mkdir(exist_ok=True)
    cfg = prov.get("config", {})
    p = float(cfg.get("confidence", 0.9))
    noise = _cell_noise_dex(f90)
    # The Table 1 beam's figures first: the slowest to draw (Fig. 3's ten log axes), they are
    # drawn (runtime.drawing) while the rest of the report is built.
    showcase = _showcase_figures(doc, run_dir, figdir, p, cfg)
    _headline(doc, run_dir, prov, fit, noise, figdir)
    colour_section(doc, run_dir, prov, figdir)  # only for a run with a colour axis (prior_model)
    _long_tables(doc, fit, noise)
    if showcase is not None:
        _showcase_section(doc, run_dir, *showcase, cfg)


def _headline(doc: Document, run_dir: Path, prov: dict, fit, noise: np.ndarray, figdir: Path) -> None:
    """What was run, the Fig. 4 analogues, what differs from the paper and why, the key
    numbers and the sky maps: the first screen of the report."""
    f90, cfg = fit.compared, prov.get("config", {})
    p = float(cfg.get("confidence", 0.9))
    n_dirs = f90[["l_deg", "b_deg"]].drop_duplicates().shape[0]
    n_bins = f90[["g_min", "g_max"]].drop_duplicates().shape[0]
    doc.heading("Optimum prior sigma_F90 over the sky against the paper (Sect. 3.4, Fig. 4)")
    doc.para(f"{len(f90)} cells ({n_dirs} directions x {n_bins} G bins, G = {f90['g_min'].min():g}-"
             f"{f90['g_max'].max():g}): {counts_text(f90['f90_flag'].value_counts().to_dict(), 'cells')}. "
             f"Confidence level P = {p:g}, R = {plain(cfg.get('ratio_R'))} /yr, sigma_F90 fixed from the "
             f"'{cfg.get('observations', {}).get('f90_case', 'two')}' case; the paper's values are its "
             "Eqs. 14-17.")
    fitted = fit.terms["s0"].notna().sum() > 0
    if fitted:
        row = []
        for name, fn, cap in (
            ("fig4_latitude.png", figures.plot_fig4_latitude, "log sigma_F90 against |sin b| per G bin (Fig. 4 left)"),
            ("fig4_coefficients.png", figures.plot_fig4_coefficients, "s0, s1, s2 against G (Fig. 4 middle)"),
            ("fig4_magnitude.png", figures.plot_fig4_magnitude, "sigma_F90 against G at b = 0, 30, 90 deg (Fig. 4 right)"),
        ):
            doc.draw(fn, fit, figdir / name)
            row.append((f"{FIG_DIR}/{name}", cap))
        doc.figure_row(row)
    # The conclusion before the numbers behind it, so both fit under the figures on one screen.
    doc.para(_difference_sentence(fit, noise, cfg, prov))
    extrapolation_para(doc, prov)
    doc.bullets(_key_numbers(fit, f90, noise, _showcase_curves(run_dir), p,
                             list(cfg.get("observations", {}).get("cases", {}))))
    maps = []
    try:
        Prior.from_run(run_dir)
        has_prior = True
    except UserInputError:  # coefficients not determined: prior_maps.fits holds NaN maps
        has_prior = False
    if has_prior:
        doc.draw(figures.plot_prior_mollweide, run_dir / MAPS_FILE, Prior.paper(), figdir / "prior_maps.png")
        maps.append((f"{FIG_DIR}/prior_maps.png", "sigma_F90 over the sky (galactic Mollweide, l = 0 at the "
                     "centre, increasing to the left) at a few G bin centres: this run's fit (prior_maps.fits) "
                     "and the paper's Eqs. 14-17"))
    if fitted:
        doc.draw(figures.plot_sky_difference, fit, figdir / "sky_difference.png")
        maps.append((f"{FIG_DIR}/sky_difference.png", "Sky map of log10(ours / paper) per cell"))
    if maps:
        doc.figure_row(maps)


def _long_tables(doc: Document, fit, noise: np.ndarray) -> None:
    """The Monte Carlo precision, the coefficients, the per-bin numbers and the cells."""
    f90 = fit.compared
    doc.heading("Coefficients, per-bin numbers and cells", level=3)
    if len(noise):
        n_ill = int(f90["ill_determined"].sum()) if "ill_determined" in f90 else 0
        doc.para(f"Monte Carlo precision: half-width of the 16-84 % bootstrap interval of sigma_F90 "
                 f"(stars resampled, `cell.n_bootstrap`) median {np.median(noise):.3f} dex, 90th percentile "
                 f"{np.percentile(noise, 90):.3f} dex over {len(noise)} cells; {_n(n_ill, 'cell')} "
                 "ill-determined (fraction within 2 binomial sigma of P over >= 1 dex of priors around the "
                 "crossing).")
    n_fitted = int(fit.terms["s0"].notna().sum())
    if n_fitted < 4:
        doc.para(f"Only {_n(n_fitted, 'G bin')} {'has' if n_fitted == 1 else 'have'} an Eq. 14 fit: the "
                 "polynomials of Eqs. 15-17 need at least 4 (s1 is cubic), so coefficients that cannot be "
                 "determined are left empty.")
    doc.table(fit.coefficients, "Coefficients of Eqs. 15-17 (increasing powers of G): ours vs the paper's; "
              "fitted_lo/hi: 16-84 % bootstrap interval over the cells (paper_inside: the paper's value "
              "lies in it)",
              {"fitted": ".5g", "fitted_lo": ".5g", "fitted_hi": ".5g", "paper": ".5g", "difference": "+.4g"})
    doc.table(fit.rms, "log10(sigma_F90 ours / paper formula) per G bin, cells with a valid sigma_F90",
              {"mean_diff_dex": "+.3f", "rms_diff_dex": ".3f"})
    term_cols = ["g"] + [c for name in ("s0", "s1", "s2") for c in (name, f"{name}_lo", f"{name}_hi")
                         if c in fit.terms] + ["n_cells", "rms_dex"]
    doc.table(fit.terms[term_cols],
              "Eq. 14 fitted per G bin, with 16-84 % bootstrap intervals (rms_dex: scatter of the cells "
              "about the fit)",
              {c: ".4f" for c in term_cols if c[:2] in ("s0", "s1", "s2")} | {"rms_dex": ".3f"})
    worst = fit.compared[fit.compared["f90_flag"] == "ok"].reindex(
        fit.compared["diff_dex"].abs().sort_values(ascending=False).index).dropna(subset=["diff_dex"]).head(10)
    doc.table(worst[["l_deg", "b_deg", "g_min", "g_max", "n_stars", "radius_deg", "sigma_f90_mas"]
                    + [c for c in ("sigma_f90_lo_mas", "sigma_f90_hi_mas") if c in worst]
                    + ["paper_sigma_f90_mas", "diff_dex"]],
              "Cells that disagree most with the paper's formula",
              {"l_deg": ".1f", "b_deg": ".1f", "radius_deg": ".2f", "sigma_f90_mas": ".3g",
               "sigma_f90_lo_mas": ".3g", "sigma_f90_hi_mas": ".3g",
               "paper_sigma_f90_mas": ".3g", "diff_dex": "+.2f"})
    frac_cols = [c for c in f90.columns if c.startswith("fraction_at_f90_")]
    if frac_cols:
        summary = f90[frac_cols].describe(percentiles=[0.1, 0.5, 0.9]).T[["count", "mean", "10%", "50%", "90%"]]
        summary.insert(0, "case", [c.removeprefix("fraction_at_f90_") for c in summary.index])
        doc.table(summary.reset_index(drop=True), "Fraction inside the P ellipse at each cell's sigma_F90, per case",
                  {"count": ".0f", "mean": ".3f", "10%": ".3f", "50%": ".3f", "90%": ".3f"})

def _n(count: int, noun: str) -> str:
    return f"{count} {noun}" + ("" if count == 1 else "s")


def _with_interval(value: float, lo: float, hi: float) -> str:
    """"1.98 [1.86, 2.10]": all three to the decimals that give the interval's half-width two
    significant digits, so the value is quoted no more precisely than it is known."""
    half = 0.5 * abs(hi - lo)
    decimals = max(0, 1 - int(np.floor(np.log10(half)))) if half > 0 else 4
    def f(x: float) -> str:
        text = f"{x:.{decimals}f}"
        return text[1:] if text.startswith("-") and float(text) == 0 else text

    return f"{f(value)} [{f(lo)}, {f(hi)}]"


def _cell_noise_dex(f90: pd.DataFrame) -> np.ndarray:
    """Per cell, the half-width [dex] of the 16-84 % bootstrap interval of sigma_F90 (empty
    when the run has no intervals)."""
    if not {"sigma_f90_lo_mas", "sigma_f90_hi_mas"} <= set(f90.columns):
        return np.array([])
    with np.errstate(divide="ignore", invalid="ignore"):
        half = 0.5 * np.log10(f90["sigma_f90_hi_mas"].to_numpy(float) / f90["sigma_f90_lo_mas"].to_numpy(float))
    return half[np.isfinite(half)]


def _showcase_curves(run_dir: Path) -> pd.DataFrame | None:
    show = sorted((run_dir / "showcase").glob("cell_*.parquet")) if (run_dir / "showcase").exists() else []
    curves = [f for f in show if not f.stem.endswith("_scatter")]
    return pd.read_parquet(curves[0]) if curves else None


def _paper_terms(g) -> dict[str, np.ndarray]:
    """s0, s1, s2 of Eq. 14 from the paper's Eqs. 15-17 at G = ``g``."""
    return {k: np.polynomial.polynomial.polyval(np.asarray(g, float), PAPER_COEFFICIENTS[k]) for k in ("s0", "s1", "s2")}


def _key_numbers(fit, f90: pd.DataFrame, noise: np.ndarray, showcase: pd.DataFrame | None, p: float,
                 cases: list[str]) -> list[str]:
    """The headline numbers, each with the interval the run provides for it."""
    items = []
    rms = fit.rms.set_index("g_bin")
    bins = rms.drop(index="all").dropna(subset=["mean_diff_dex"])
    if "all" in rms.index and rms.loc["all", "n_cells"] > 0:
        a = rms.loc["all"]
        text = (f"Difference from the paper, log10(ours / Eqs. 14-17) over the {int(a['n_cells'])} cells with a "
                f"sigma_F90: RMS {a['rms_diff_dex']:.3f} dex, mean {a['mean_diff_dex']:+.3f} dex")
        if len(noise):
            text += (f"; a cell's own Monte Carlo uncertainty is {np.median(noise):.3f} dex (median half-width "
                     "of its 16-84 % bootstrap interval)")
        items.append(text + ".")
    if len(bins) > 1:
        lo, hi = bins["mean_diff_dex"].idxmin(), bins["mean_diff_dex"].idxmax()
        items.append(f"Mean difference per G bin from {bins.loc[lo, 'mean_diff_dex']:+.3f} dex (G = {lo}) to "
                     f"{bins.loc[hi, 'mean_diff_dex']:+.3f} dex (G = {hi}); RMS per bin "
                     f"{bins['rms_diff_dex'].min():.3f}-{bins['rms_diff_dex'].max():.3f} dex.")
    coef = fit.coefficients
    if coef["fitted"].notna().any():
        for name, eq in (("s0", 15), ("s1", 16), ("s2", 17)):
            rows = coef[coef["term"].str.startswith(f"{name}_")]
            parts = []
            for r in rows.itertuples(index=False):
                power = r.term.split("_c")[1]
                if not np.isfinite(r.fitted):
                    parts.append(f"c{power} not determined (paper {r.paper:g})")
                    continue
                if "fitted_lo" in coef and np.isfinite(r.fitted_lo):
                    parts.append(f"c{power} {_with_interval(r.fitted, r.fitted_lo, r.fitted_hi)} (paper {r.paper:g})")
                else:
                    parts.append(f"c{power} {r.fitted:.3g} (paper {r.paper:g})")
            items.append(f"{name} (Eq. {eq}) coefficients, ours [16-84 %] (paper): " + ", ".join(parts) + ".")
        if "paper_inside" in coef:
            inside = coef.loc[coef["paper_inside"].astype(bool), "term"].str.replace("_", " ").tolist()
            items.append(f"The paper's coefficient lies inside our 16-84 % interval for {len(inside)} of "
                         f"{len(coef)} terms" + (f" ({', '.join(inside)})." if inside else "."))
    terms = fit.terms.dropna(subset=["s0", "s1", "s2"])
    if len(terms) and {"s0_lo", "s0_hi"} <= set(terms.columns):
        paper = _paper_terms(terms["g"])
        outside = {k: int(((paper[k] < terms[f"{k}_lo"]) | (paper[k] > terms[f"{k}_hi"])).sum())
                   for k in ("s0", "s1", "s2")}
        items.append("Eq. 14 per G bin: the paper's term lies outside our 16-84 % interval in "
                     f"{outside['s0']} of {len(terms)} bins for s0 (constant), {outside['s1']} for s1 (|sin b|) "
                     f"and {outside['s2']} for s2 (cos b cos l).")
    if showcase is not None and len(showcase):
        r = showcase.iloc[0]
        g = (float(r["g_min"]) + float(r["g_max"])) / 2
        paper = float(evaluate_formula(PAPER_COEFFICIENTS, float(r["l_deg"]), float(r["b_deg"]), g))
        iv = (f" [{r['sigma_f90_lo_mas']:.3g}, {r['sigma_f90_hi_mas']:.3g}]"
              if {"sigma_f90_lo_mas", "sigma_f90_hi_mas"} <= set(showcase.columns) else "")
        items.append(f"The paper's Table 1 beam, (l, b) = ({r['l_deg']:.1f}, {r['b_deg']:.1f}) deg, "
                     f"G = {r['g_min']:g}-{r['g_max']:g}: sigma_F90 = {r['sigma_f90_mas']:.3g} mas{iv} "
                     f"(16-84 %), the paper's formula {paper:.3g} mas.")
    # In the config's order of the cases (one, two, ..., eight), not the pivot's alphabetical one.
    frac_cols = sorted((c for c in f90.columns if c.startswith("fraction_at_f90_")),
                       key=lambda c: (cases.index(c[16:]) if c[16:] in cases else len(cases), c))
    if frac_cols:
        med = f90[frac_cols].median()
        items.append(f"At each cell's sigma_F90 the median fraction inside the P = {p:g} ellipse is "
                     f"{med.min():.3f}-{med.max():.3f} over the {len(frac_cols)} observation cases "
                     f"({', '.join(c.removeprefix('fraction_at_f90_') for c in frac_cols)}): one prior serves "
                     "every case, as in the paper's Fig. 3.")
    return items


#: Where the reasons for a difference from the paper are written down.
_DOCS_MODEL = "docs/galaxy_model.md, 'Default sweep and Table 2'"
_DOCS_DIFFERENCES = "docs/architecture.md, 'Known modelling differences'"
#: Faint edge of the bins where the galaxy model's bright-star calibration puts the
#: default sweep's sigma_F90 above the paper's by +0.05 dex or more (docs/galaxy_model.md,
#: G = 6-12 with besancon-r03-3; README: +0.10 to +0.11 dex at G = 6-10 with r03-4).
_BRIGHT_G = 12.0


def _difference_sentence(fit, noise: np.ndarray, cfg: dict, prov: dict) -> str:
    """One sentence: the G bin that differs most, by how much against the noise, and the
    documented reason for a difference of that kind."""
    bins = fit.compared[fit.compared["f90_flag"] == "ok"].dropna(subset=["diff_dex"])
    if bins.empty:
        return "No cell has a sigma_F90, so nothing can be compared with the paper."
    per_bin = bins.groupby(["g_min", "g_max"])["diff_dex"].agg(["mean", "count"])
    g0, g1 = per_bin["mean"].abs().idxmax()
    worst = per_bin.loc[(g0, g1)]
    mean = float(worst["mean"])
    # Uncertainty of a bin's mean from the cells' own Monte Carlo noise alone.
    sigma = float(np.median(noise)) / np.sqrt(worst["count"]) if len(noise) else float("nan")
    text = (f"Our sigma_F90 differs most from the paper's at G = {g0:g}-{g1:g}, by {mean:+.3f} dex on average "
            f"(our prior {'looser' if mean > 0 else 'tighter'} than the paper's")
    if np.isfinite(sigma) and sigma > 0:
        text += f"; {abs(mean) / sigma:.0f} x the {sigma:.3f} dex Monte Carlo uncertainty of that mean"
        if abs(mean) < 2 * sigma:
            return text + "), which is within the noise of this run."
    text += ")"
    pop = cfg.get("population", {}).get("name", "galaxy_model")
    law = cfg.get("scanning", {}).get("name")
    if pop == "galaxy_model" and g1 <= _BRIGHT_G and mean > 0:
        return (text + ": the built-in galaxy model's bright stars follow the published local densities and "
                "counts of the real sky, which puts them nearer than in GUMS, on which Eqs. 14-17 were "
                f"fitted, so their parallaxes and sigma_F90 are larger ({_DOCS_MODEL}).")
    source = (f"the built-in galaxy model ({prov.get('galaxy_model_version') or 'version not recorded'})"
              if pop == "galaxy_model" else f"the '{pop}' population")
    return (text + f": Eqs. 14-17 were fitted to GUMS stars on the pre-launch nominal scanning law, this run "
            f"draws {source}" + (f" on the '{law}' law" if law and law != "nominal" else "")
            + f", whose star counts and distances differ from GUMS ({_DOCS_DIFFERENCES}; {_DOCS_MODEL}).")


def _showcase_figures(doc: Document, run_dir: Path, figdir: Path, p: float, cfg: dict):
    """Draw Figs. 1-3 of the showcase cell; returns its curves, sigma_F90 and whether Fig. 2
    was drawn, or None without a showcase cell."""
    show = sorted((run_dir / "showcase").glob("cell_*.parquet")) if (run_dir / "showcase").exists() else []
    curves_files = [f for f in show if not f.stem.endswith("_scatter")]
    if not curves_files:
        return None
    curves = pd.read_parquet(curves_files[0])
    scatter_file = curves_files[0].with_name(curves_files[0].stem + "_scatter.parquet")
    f90 = float(curves["sigma_f90_mas"].iloc[0])
    case = cfg.get("observations", {}).get("f90_case", "two")
    doc.draw(figures.plot_showcase_cases, curves, f90, figdir / "fig3_cases.png", p)
    doc.draw(figures.plot_showcase_curves, curves, case, f90, figdir / "fig1_curves.png", p)
    if scatter_file.exists():
        doc.draw(figures.plot_showcase_scatter, pd.read_parquet(scatter_file), figdir / "fig2_scatter.png", p)
    return curves, f90, scatter_file.exists()


def _showcase_section(doc: Document, run_dir: Path, curves: pd.DataFrame, f90: float, with_scatter: bool,
                      cfg: dict) -> None:
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
    doc.figure(f"{FIG_DIR}/fig1_curves.png", "Actual errors and formal uncertainty against the prior (Fig. 1)")
    if with_scatter:
        doc.figure(f"{FIG_DIR}/fig2_scatter.png", "Actual position errors and the confidence ellipse for a "
                   "tight prior, sigma_F90 and a loose prior (Fig. 2)")
    doc.figure(f"{FIG_DIR}/fig3_cases.png", "1, 2, 2 diluted, 4 and 8 distinct transits (Fig. 3)")
    groups_file = run_dir / "showcase" / "groups.csv"
    if groups_file.exists():
        _showcase_groups_note(doc, pd.read_csv(groups_file), (float(r["ra_deg"]), float(r["dec_deg"])), cfg)


def _showcase_groups_note(doc: Document, groups: pd.DataFrame, ra_dec: tuple[float, float], cfg: dict) -> None:
    """The showcase's distinct transits, which of them each case uses, and Table 1's differences."""
    cases = cfg.get("observations", {}).get("cases", {})
    n = len(groups)
    used = {c: [groups["group"].iloc[i] for i in idx if -n <= int(i) < n] for c, idx in cases.items()}
    groups = groups.assign(cases=[", ".join(c for c, gs in used.items() if g in gs) for g in groups["group"]])
    doc.table(groups, "Distinct transits (visits) of the showcase direction and the cases that use them",
              {"scan_angle_deg": ".1f"})
    law = cfg.get("scanning", {}).get("name", "?")
    text = (f"Cases take distinct transits by number; here the {n} visits come from the '{law}' "
            "scanning law.")
    if "eight" in used and len(used["eight"]) == 8:
        last = groups.loc[groups["group"] == used["eight"][-1], "last_utc"].iloc[0][:10]
        text += f" The 'eight' case ends on {last}."
    if np.allclose(ra_dec, TABLE1_RA_DEC_DEG):
        ours = pd.to_datetime(groups["first_utc"]).to_numpy()
        paper = pd.to_datetime(pd.Series(TABLE1_GROUP_STARTS_UTC)).to_numpy()
        # The 2015 rows of Table 1 are one 6 h spin off the flown law: match within 1 day.
        near = np.abs(ours[:, None] - paper[None, :]) <= np.timedelta64(1, "D")
        extra = groups["first_utc"][~near.any(axis=1)].str[:10].tolist()
        missing = [d[:10] for d, hit in zip(TABLE1_GROUP_STARTS_UTC, near.any(axis=0)) if not hit]
        if extra or missing:
            text += (" This is the paper's Table 1 star, whose 8 groups (computed before launch with "
                     f"the nominal law) end on {TABLE1_GROUP_STARTS_UTC[-1][:10]}. Visits here that Table 1 "
                     f"lacks: {', '.join(extra) or 'none'}; Table 1 groups not found here: "
                     f"{', '.join(missing) or 'none'}. The cases are therefore not the paper's: "
                     "a case that reaches past an extra visit uses it instead of a later Table 1 group"
                     + (f" (the 'eight' case ends on {last} instead of {TABLE1_GROUP_STARTS_UTC[-1][:10]})."
                        if "eight" in used and len(used["eight"]) == 8 else "."))
        else:
            text += " Its visits are the 8 groups of the paper's Table 1 (within 1 day)."
    doc.para(text)
