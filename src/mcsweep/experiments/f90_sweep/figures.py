"""Figures of the F90 sweep's report (PNG): analogues of the paper's Figs. 1-4 and sky maps
of the fitted prior and of its difference from the paper's formula."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402
from matplotlib.ticker import LogLocator  # noqa: E402

from ...astrometry.confidence import binomial_interval  # noqa: E402
from ...runtime.document import save_png  # noqa: E402
from .fit import PAPER_COEFFICIENTS, FitResult, direction_design, evaluate_formula  # noqa: E402

__all__ = [
    "plot_fig4_latitude",
    "plot_fig4_coefficients",
    "plot_fig4_magnitude",
    "plot_sky_difference",
    "plot_prior_mollweide",
    "plot_showcase_curves",
    "plot_showcase_scatter",
    "plot_showcase_cases",
]

_CASE_LABELS = {"one": "1 transit", "two": "2 transits", "two_diluted": "2 transits (diluted)",
                "four": "4 transits", "eight": "8 transits"}


def plot_fig4_latitude(fit: FitResult, path: Path) -> Path:
    """Fig. 4 left: log sigma_F90 minus the longitude term against |sin b|, per G bin."""
    c = fit.compared[fit.compared["f90_flag"] == "ok"]
    terms = fit.terms.set_index(["g_min", "g_max"])
    fig, ax = plt.subplots(figsize=(6.5, 5))
    cmap = plt.get_cmap("viridis")
    bins = sorted(set(zip(c["g_min"], c["g_max"])))
    for i, (g0, g1) in enumerate(bins):
        grp = c[(c["g_min"] == g0) & (c["g_max"] == g1)]
        t = terms.loc[(g0, g1)]
        x = direction_design(grp["l_deg"], grp["b_deg"])
        y = np.log10(grp["sigma_f90_mas"]) - t["s2"] * x[:, 2]
        color = cmap(i / max(len(bins) - 1, 1))
        pos = np.cos(np.radians(grp["l_deg"])) > 0
        if {"sigma_f90_lo_mas", "sigma_f90_hi_mas"} <= set(grp.columns):
            # Each cell's 16-84 % bootstrap interval of sigma_F90, in the same dex.
            with np.errstate(divide="ignore", invalid="ignore"):
                lo = np.log10(grp["sigma_f90_mas"]) - np.log10(grp["sigma_f90_lo_mas"])
                hi = np.log10(grp["sigma_f90_hi_mas"]) - np.log10(grp["sigma_f90_mas"])
            yerr = np.vstack([np.nan_to_num(np.clip(lo, 0, None), posinf=0.0),
                              np.nan_to_num(np.clip(hi, 0, None), posinf=0.0)])
            ax.errorbar(x[:, 1], y, yerr=yerr, fmt="none", ecolor=color, elinewidth=0.6, alpha=0.6)
        ax.scatter(x[pos, 1], y[pos], s=14, facecolors="none", edgecolors=[color])
        ax.scatter(x[~pos, 1], y[~pos], s=18, marker="+", color=color)
        xs = np.linspace(0, 1, 2)
        ax.plot(xs, t["s0"] + t["s1"] * xs, color=color, lw=1, label=f"G={g0:g}-{g1:g}")
        gm = 0.5 * (g0 + g1)
        pv = np.polynomial.polynomial.polyval
        ax.plot(xs, pv(gm, PAPER_COEFFICIENTS["s0"]) + pv(gm, PAPER_COEFFICIENTS["s1"]) * xs, ":",
                color=color, lw=1)
    ax.set_xlabel("|sin b|")
    ax.set_ylabel(r"log$_{10}$ $\sigma_{\varpi,F90}$ [mas] $-$ $s_2\cos b\cos l$")
    ax.set_title("Eq. 14 per G bin (o: cos l > 0, +: cos l < 0; bars: bootstrap 16-84 %;\n"
                 "solid: our fit, dotted: the paper's)", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    return save_png(fig, path)


def plot_fig4_coefficients(fit: FitResult, path: Path) -> Path:
    """Fig. 4 middle: s0, s1, s2 against G with our polynomial fits and the paper's.

    Each G bin's term carries its 16-84 % bootstrap interval over the cells (columns
    ``s0_lo`` ... of ``fit.terms``) as an error bar, next to the paper's Eqs. 15-17.
    """
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    g = np.linspace(6, 20, 200)
    pv = np.polynomial.polynomial.polyval
    t = fit.terms
    for name, color in (("s0", "C0"), ("s1", "C1"), ("s2", "C2")):
        y = t[name].to_numpy(float)
        if {f"{name}_lo", f"{name}_hi"} <= set(t.columns):
            lo, hi = t[f"{name}_lo"].to_numpy(float), t[f"{name}_hi"].to_numpy(float)
            yerr = np.vstack([np.clip(y - lo, 0, None), np.clip(hi - y, 0, None)])
            ax.errorbar(t["g"], y, yerr=yerr, fmt="o", ms=4, capsize=2, color=color,
                        label=f"{name} per G bin (16-84 % bootstrap)")
        else:
            ax.plot(t["g"], y, "o", color=color, label=f"{name} (per G bin)")
        ax.plot(g, pv(g, fit.fitted[name]), "-", color=color, label=f"{name} fit (Eqs. 15-17 form)")
        ax.plot(g, pv(g, PAPER_COEFFICIENTS[name]), "--", color=color, label=f"{name} paper")
    ax.set_xlabel("G [mag]")
    ax.set_ylabel("coefficient [dex]")
    ax.set_title("Coefficients of Eq. 14 against G")
    ax.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.12))
    return save_png(fig, path)


def plot_fig4_magnitude(fit: FitResult, path: Path) -> Path:
    """Fig. 4 right: sigma_F90 against G at b = 0, 30, 90 deg and l = 0, 90, 180 deg."""
    fig, ax = plt.subplots(figsize=(6.5, 5))
    g = np.linspace(6, 20, 200)
    styles = {0: "-", 90: "--", 180: "-."}
    for b, color in ((0, "C3"), (30, "C2"), (90, "C0")):
        for l, ls in styles.items():
            lab = f"b={b}°, l={l}°"
            ax.plot(g, evaluate_formula(fit.fitted, l, b, g), ls, color=color, label=f"ours {lab}")
            ax.plot(g, evaluate_formula(PAPER_COEFFICIENTS, l, b, g), ls, color=color, alpha=0.35, lw=3,
                    label=f"paper {lab}")
    ax.set_yscale("log")
    ax.set_xlabel("G [mag]")
    ax.set_ylabel(r"$\sigma_{\varpi,F90}$ [mas]")
    ax.set_title("Fitted prior (thin) vs the paper's Eqs. 14-17 (thick, faint)")
    ax.legend(fontsize=5.5, ncol=2)
    return save_png(fig, path)


def plot_sky_difference(fit: FitResult, path: Path) -> Path:
    """Mollweide map of log10(ours / paper) per direction, averaged over G bins."""
    c = fit.compared[fit.compared["f90_flag"] == "ok"]
    agg = c.groupby(["l_deg", "b_deg"], as_index=False)["diff_dex"].mean()
    fig = plt.figure(figsize=(7.5, 4.2))
    ax = fig.add_subplot(111, projection="mollweide")
    lon = np.radians(((agg["l_deg"] + 180) % 360) - 180)
    vmax = max(0.1, float(np.nanmax(np.abs(agg["diff_dex"])))) if len(agg) else 1
    sc = ax.scatter(-lon, np.radians(agg["b_deg"]), c=agg["diff_dex"], cmap="RdBu_r", vmin=-vmax, vmax=vmax,
                    s=120, edgecolors="k", linewidths=0.3)
    ax.set_xticklabels([f"{v}°" for v in (150, 120, 90, 60, 30, 0, 330, 300, 270, 240, 210)], fontsize=7)
    ax.grid(True, alpha=0.3)
    fig.colorbar(sc, ax=ax, orientation="horizontal", pad=0.08, shrink=0.6,
                 label=r"mean over G of log$_{10}$($\sigma_{F90}$ ours / paper) [dex]")
    ax.set_title("Galactic coordinates (l increases to the left)", fontsize=9)
    return save_png(fig, path)


#: Probability of the shaded binomial band of the fraction inside (as the 16-84 %
#: interval of sigma_F90).
BAND_LEVEL = 0.68


def _f90_band(ax, curves: pd.DataFrame, label: bool = False) -> None:
    """Shade the bootstrap interval of sigma_F90 (columns sigma_f90_lo/hi_mas) if present."""
    if not {"sigma_f90_lo_mas", "sigma_f90_hi_mas"} <= set(curves.columns):
        return
    lo, hi = float(curves["sigma_f90_lo_mas"].iloc[0]), float(curves["sigma_f90_hi_mas"].iloc[0])
    if np.isfinite(lo) and np.isfinite(hi):
        ax.axvspan(lo, hi, color="0.5", alpha=0.25, lw=0,
                   label=f"σF90 16-84 %: {lo:.3g}-{hi:.3g} mas" if label else None)


def plot_showcase_curves(curves: pd.DataFrame, case: str, f90: float, path: Path, p: float) -> Path:
    """Fig. 1: P-th percentile of actual errors and median semi-major axis vs the prior."""
    c = curves[(curves["case"] == case) & ~curves["at_f90"]]
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(c["sigma_prior_mas"], c["p_error_mas"], "b--", label=f"{100*p:g}th percentile of actual errors")
    ax.plot(c["sigma_prior_mas"], c["median_semi_major_mas"], "r-",
            label=f"semi-major axis of {100*p:g}% ellipse (median)")
    if np.isfinite(f90):
        ax.axvline(f90, color="k", lw=1, label=f"σF90 = {f90:.3g} mas")
        _f90_band(ax, curves, label=True)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(r"parallax prior $\sigma_{\varpi,p}$ [mas]")
    ax.set_ylabel("position error / uncertainty [mas]")
    ax.set_title(f"Table 1 beam, {_CASE_LABELS.get(case, case)} (paper Fig. 1)")
    ax.legend(fontsize=8)
    return save_png(fig, path)


def plot_showcase_scatter(scatter: pd.DataFrame, path: Path, p: float) -> Path:
    """Fig. 2: actual position errors with the P-confidence ellipse for three priors."""
    from ...astrometry.confidence import chi2_threshold, inside_counts

    k = chi2_threshold(p, 2)
    priors = list(dict.fromkeys(scatter["prior"]))
    order = sorted(priors, key=lambda lab: scatter.loc[scatter["prior"] == lab, "sigma_prior_mas"].iloc[0])
    fig, axes = plt.subplots(len(order), 1, figsize=(5, 4.2 * len(order)))
    for ax, lab in zip(np.atleast_1d(axes), order):
        s = scatter[scatter["prior"] == lab]
        ax.plot(s["dra_mas"], s["ddec_mas"], ".", color="C0", ms=2)
        cov = np.array([[s["cov_aa"].median(), s["cov_ad"].median()],
                        [s["cov_ad"].median(), s["cov_dd"].median()]])
        w, v = np.linalg.eigh(cov)
        angle = np.degrees(np.arctan2(v[1, 1], v[0, 1]))
        ell = Ellipse((0, 0), 2 * np.sqrt(k * w[1]), 2 * np.sqrt(k * w[0]), angle=angle,
                      fill=False, color="r", lw=1.5)
        ax.add_patch(ell)
        dpos = s[["dra_mas", "ddec_mas"]].to_numpy(float)
        cov2 = s[["cov_aa", "cov_ad", "cov_ad", "cov_dd"]].to_numpy(float).reshape(-1, 2, 2)
        n_in, n_valid = inside_counts(dpos, cov2, p)
        lim = np.nanpercentile(np.hypot(s["dra_mas"], s["ddec_mas"]), 98) * 1.2
        ax.set_xlim(lim, -lim)  # east to the left, as on the sky
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_xlabel(r"$\Delta\alpha*$ [mas]")
        ax.set_ylabel(r"$\Delta\delta$ [mas]")
        frac = f"{100 * n_in / n_valid:.1f}%" if n_valid else "–"
        ax.set_title(f"prior {lab} (σ = {s['sigma_prior_mas'].iloc[0]:.3g} mas): "
                     f"{frac} inside ({n_in}/{n_valid} with a region, {len(s)} stars)", fontsize=9)
    return save_png(fig, path)


def plot_showcase_cases(curves: pd.DataFrame, f90: float, path: Path, p: float) -> Path:
    """Fig. 3: for each case, error/uncertainty curves (left) and the fraction inside (right)."""
    cases = list(dict.fromkeys(curves["case"]))
    fig, axes = plt.subplots(len(cases), 2, figsize=(9, 2.6 * len(cases)), squeeze=False)
    for row, case in zip(axes, cases):
        c = curves[(curves["case"] == case) & ~curves["at_f90"]]
        row[0].plot(c["sigma_prior_mas"], c["p_error_mas"], "b--", label="actual errors")
        row[0].plot(c["sigma_prior_mas"], c["median_semi_major_mas"], "r-", label="formal (semi-major)")
        row[0].set_yscale("log")
        row[0].yaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
        row[0].set_ylabel("[mas]")
        row[1].plot(c["sigma_prior_mas"], 100 * c["fraction_inside"], "k-")
        if {"n_inside", "n_valid"} <= set(c.columns):
            lo, hi = binomial_interval(c["n_inside"], c["n_valid"], BAND_LEVEL)
            row[1].fill_between(c["sigma_prior_mas"], 100 * lo, 100 * hi, color="0.6", alpha=0.5, lw=0,
                                label=f"binomial {100 * BAND_LEVEL:g} % band")
        row[1].axhline(100 * p, color="gray", lw=0.8)
        row[1].set_ylim(0, 100)
        row[1].set_ylabel("% inside ellipse")
        for ax in row:
            ax.set_xscale("log")
            # minor ticks at 2 and 5 of each decade: the figure's ten logarithmic axes built
            # about a thousand tick objects, most of the report's time
            ax.xaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
            if np.isfinite(f90):
                ax.axvline(f90, color="k", lw=1)
                _f90_band(ax, curves)
            ax.set_title(_CASE_LABELS.get(case, case), fontsize=9)
    for ax in axes[-1]:
        ax.set_xlabel(r"$\sigma_{\varpi,p}$ [mas]")
    axes[0, 0].legend(fontsize=7)
    return save_png(fig, path)


def plot_prior_mollweide(maps_path: Path, paper_prior, path: Path, n_bins: int = 3) -> Path:
    """sigma_F90 maps of a run (``prior_maps.fits``) next to the paper's formula.

    Rows: up to ``n_bins`` G values (the brightest, middle and faintest bin centres);
    columns: this run's map and the paper's Eqs. 14-17 at the same pixel centres, on one
    logarithmic colour scale per row. Galactic Mollweide, l = 0 at the centre and
    increasing to the left (the astronomers' convention).
    """
    from astropy.coordinates import Galactic, Longitude
    from astropy_healpix import HEALPix
    from astropy import units as u
    from matplotlib.colors import LogNorm

    from ...prior.maps import read_prior_maps

    nside, g_values, maps = read_prior_maps(maps_path)
    pick = sorted(set(np.linspace(0, len(g_values) - 1, min(n_bins, len(g_values))).round().astype(int)))
    hp = HEALPix(nside=nside, order="ring", frame=Galactic())
    # A mesh of about half a HEALPix pixel (at most 1 deg): every pixel shows, and no more
    # quads are drawn than that needs (at nside 16, 3.4 x fewer than a 1 deg mesh).
    step = min(1.0, 0.5 * hp.pixel_resolution.to_value(u.deg))
    n_lon = int(np.ceil(360.0 / step))
    lon_e = np.linspace(-np.pi, np.pi, n_lon + 1)
    lat_e = np.linspace(-np.pi / 2, np.pi / 2, n_lon // 2 + 1)
    lon_c, lat_c = np.meshgrid(0.5 * (lon_e[1:] + lon_e[:-1]), 0.5 * (lat_e[1:] + lat_e[:-1]))
    # Plot x = -l so that l grows to the left.
    pix = hp.lonlat_to_healpix(Longitude(-lon_c * u.rad), lat_c * u.rad)
    pl, pb = hp.healpix_to_lonlat(np.arange(hp.npix))
    fig, axes = plt.subplots(len(pick), 2, figsize=(10, 2.9 * len(pick)), subplot_kw={"projection": "mollweide"},
                             squeeze=False)
    for row, i in enumerate(pick):
        ours = maps[i]
        paper = paper_prior.sigma_parallax_mas(pl.deg, pb.deg, g_values[i])
        finite = np.concatenate([ours[np.isfinite(ours)], paper])
        norm = LogNorm(vmin=finite.min(), vmax=finite.max())
        for col, (values, label) in enumerate(((ours, "this run (fit)"), (paper, "paper Eqs. 14-17"))):
            ax = axes[row, col]
            mesh = ax.pcolormesh(lon_e, lat_e, values[pix], norm=norm, cmap="viridis", shading="flat")
            ax.set_title(f"G = {g_values[i]:g}: {label}", fontsize=9)
            ax.set_xticklabels([])
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.3)
        fig.colorbar(mesh, ax=axes[row, :].tolist(), shrink=0.8, label="sigma_F90 [mas]")
    return save_png(fig, path, trim=True)
