"""Validation report of the built-in galaxy model against the paper and published counts.

Run ``python -m mcsweep.validation.population_validation --out results/population_validation``.
Writes ``report.md``, ``ratio_cells.csv``, ``counts.csv`` and three PNG figures.

Checks:

1. Table 1 beam: 1 deg around (l, b) = (245.7, 46.5) deg, G = 15 +- 0.5 holds 458 GUMS
   stars; the model should give 458 within +-10 % (the target the model is calibrated to,
   docs/galaxy_model.md).
2. Median proper motion / parallax at G = 15: about 10 /yr in GUMS (paper Sect. 3.1);
   accepted range 6-15 /yr.
3. The paper's footnote (Sect. 3.4): sigma_F90(l, b, G) of Eqs. 14-17 is about 0.5-0.8
   times the 90th percentile of the parallaxes. The ratio is tabulated over the 48
   HEALPix nside = 2 pixel centres (Galactic frame, nested order: "48 directions
   uniformly distributed on the sky", the sweep's ``sky=healpix48``) x G = 6..20 (1-mag
   bins centred on G). Beams start at 1 deg and widen until 1000 stars are expected (at
   most 20 deg) with the sweep's own rule (:func:`mcsweep.experiments.f90_sweep.pencil_beam.beam_radius`);
   up to 2000 stars are drawn per cell.
4. All-sky counts per G magnitude against the published totals cited in the report.
5. The published facts the model is calibrated to (:mod:`.published_counts`): all-sky counts per 1-mag G
   bin against Tycho-2/UCAC4 and, with the optional extra ``realsky``, Gaia DR3's own
   counts at G < 10 (``published_counts.csv``, ``published_counts.png``), the
   sources within 100 pc against the Gaia Catalogue of Nearby Stars, the local
   luminosity function per 1-mag M_G bin against Bovy (2017) (``local_lf.csv``,
   ``local_lf.png``), the local content against the GCNS within 60 pc and the CNS5
   within 25 pc (``local_census.csv``), the local density per spectral class against
   Mamajek's volume-complete samples, Holberg et al. (2002) for white dwarfs and the
   CNS5 (``local_density_by_class.csv``/``.png``), the 90th percentile of parallax at G = 6-7 per
   |b| band (``bright_parallax.csv``), and the model version.

It uses the stages after the population (the prior's Eqs. 14-17, the sweep's directions and
the pencil-beam widening), so it sits with the other validation tools, not in the population
stage.
"""

from __future__ import annotations

import argparse
import errno
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from ..experiments.f90_sweep.pencil_beam import beam_radius
from ..population import GalaxyModel
from ..population.galaxy.parameters import MODEL_VERSION
from . import published_counts as pc
from ..prior import sigma_f90
from ..experiments.f90_sweep.cells import sky_directions
from ..experiments.f90_sweep.conf import SkyConf

__all__ = ["healpix48_centres", "ratio_table", "main"]

#: Paper Table 1 beam and its GUMS count.
BEAM = dict(l_deg=245.7, b_deg=46.5, radius_deg=1.0, g_min=14.5, g_max=15.5)
GUMS_BEAM_COUNT = 458
BEAM_TOLERANCE = 0.10
MU_PLX_RANGE = (6.0, 15.0)       # 1/yr
RATIO_RANGE = (0.4, 1.0)         # accepted range of sigma_F90 / p90, wider than the footnote's
FOOTNOTE_RANGE = (0.5, 0.8)      # the paper's footnote
MIN_STARS, MAX_STARS, MAX_RADIUS_DEG = 1000, 2000, 20.0
#: Published all-sky numbers, each read in the cited place [V].
PUBLISHED = [
    ("GUMS-10, G < 20 (Robin et al. 2012, A&A 543, A100; CDS VI/137) [V]", None, 20.0, 1.1e9),
    ("Gaia DR3 sources with G, G <~ 21, incomplete beyond G ~ 19-20 "
     "(Gaia Collaboration, Vallenari et al. 2023) [V]", None, 21.0, 1_811_709_771),
    ("Gaia DR2 sources, G <~ 21 (Gaia Collaboration, Brown et al. 2018) [V]", None, 21.0,
     1_692_919_135),
    ("Yale Bright Star Catalogue, 5th rev. ed., V < 6.5: 9096 stars of its 9110 objects "
     "(Hoffleit & Warren 1991, CDS V/50 ReadMe; model: G < 6.3) [V]", None, 6.3, 9096),
]


def healpix48_centres():
    """Galactic (l, b) in deg of the sweep's default directions (48 HEALPix nside = 2 centres)."""
    dirs = sky_directions(SkyConf())
    return np.array([d.l_deg for d in dirs]), np.array([d.b_deg for d in dirs])


def ratio_table(model, rng, g_centres=range(6, 21)):
    """sigma_F90 / p90(parallax) over the 48 directions x G bins (DataFrame)."""
    rows = []
    for pix, (l, b) in enumerate(zip(*healpix48_centres())):
        for g in g_centres:
            g0, g1 = g - 0.5, g + 0.5
            r, n = beam_radius(model, l, b, g0, g1, radius_deg=1.0, min_stars=MIN_STARS,
                               max_radius_deg=MAX_RADIUS_DEG)
            df = model.sample_cone(l, b, r, g0, g1, rng, max_stars=MAX_STARS)
            p90 = float(np.percentile(df.parallax, 90)) if len(df) else np.nan
            mu_plx = float(np.median(np.hypot(df.pmra, df.pmdec) / df.parallax)) if len(df) else np.nan
            s = float(sigma_f90(l, b, g))
            rows.append(dict(pixel=pix, l_deg=l, b_deg=b, G=g, radius_deg=r, n_expected=n,
                             n_drawn=len(df), p90_parallax_mas=p90, sigma_f90_mas=s,
                             ratio=s / p90, median_mu_over_plx=mu_plx))
    return pd.DataFrame(rows)


def _beam_section(model, rng):
    exp = model.expected_count(**BEAM)
    by_pop = model.expected_count_by_population(**BEAM)
    df = model.sample_cone(**BEAM, rng=rng)
    mu_plx = float(np.median(np.hypot(df.pmra, df.pmdec) / df.parallax))
    variants = {
        "default": exp,
        "counting stars, not systems (multiplicity_frequency=0)":
            GalaxyModel(multiplicity_frequency=0.0).expected_count(**BEAM),
        "thin_disc_scale_height_factor=0.8": GalaxyModel(thin_disc_scale_height_factor=0.8).expected_count(**BEAM),
        "thin_disc_scale_height_factor=1.25": GalaxyModel(thin_disc_scale_height_factor=1.25).expected_count(**BEAM),
        "extinction=false": GalaxyModel(extinction=False).expected_count(**BEAM),
    }
    return exp, by_pop, len(df), mu_plx, variants


def _sky_section(model, rng, n_sky):
    rows = []
    for g in range(3, 21):
        by = model.expected_count_by_population(0, 90, 180, g, g + 1)
        rows.append(dict(G_min=g, G_max=g + 1, total=sum(by.values()), **by))
    counts = pd.DataFrame(rows)
    counts["cumulative"] = counts["total"].cumsum() + model.expected_count(0, 90, 180, -5, 3)
    sky = model.sample_sky(14.5, 15.5, rng, max_stars=n_sky)
    mu_plx_sky = float(np.median(np.hypot(sky.pmra, sky.pmdec) / sky.parallax))
    published = [(name, cut, value, model.expected_count(0, 90, 180, -5, cut))
                 for name, _, cut, value in PUBLISHED]
    return counts, mu_plx_sky, published


def _figures(out, cells, counts, published, model):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    piv = cells.pivot(index="pixel", columns="G", values="ratio")
    im = ax[0].imshow(np.log10(piv.to_numpy()), aspect="auto", cmap="coolwarm", vmin=-0.6, vmax=0.6,
                      extent=(5.5, 20.5, 47.5, -0.5))
    ax[0].set_xlabel("G [mag]")
    ax[0].set_ylabel("HEALPix nside=2 pixel (Galactic, nested)")
    ax[0].set_title("log10(sigma_F90 / p90 parallax)")
    fig.colorbar(im, ax=ax[0])
    ax[1].hist(cells["ratio"], bins=np.geomspace(0.1, 5, 50), color="0.5")
    for x in RATIO_RANGE:
        ax[1].axvline(x, color="k", ls="--")
    for x in FOOTNOTE_RANGE:
        ax[1].axvline(x, color="tab:red", ls=":")
    ax[1].set_xscale("log")
    ax[1].set_xlabel("sigma_F90 / p90 parallax (dashed: 0.4-1.0, dotted: footnote 0.5-0.8)")
    ax[1].set_ylabel("cells")
    fig.tight_layout()
    fig.savefig(out / "ratio_sigma_f90_p90.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    g = counts["G_min"] + 0.5
    for pop in ("thin_disc", "thick_disc", "halo", "bulge"):
        if pop in counts:
            ax[0].semilogy(g, counts[pop], "o-", ms=3, label=pop)
    ax[0].semilogy(g, counts["total"], "k-", lw=2, label="total")
    ax[0].set_ylim(0.1, None)
    ax[0].set_xlabel("G [mag] (1-mag bins)")
    ax[0].set_ylabel("stars on the whole sky per mag")
    ax[0].legend()
    ax[1].semilogy(counts["G_max"], counts["cumulative"], "k-", label="model N(<G)")
    for i, (name, cut, value, mod) in enumerate(published):
        ax[1].semilogy([cut], [value], "s", label=name.split(" (")[0] + f" ({value:.3g})")
    ax[1].set_xlabel("G limit [mag]")
    ax[1].set_ylabel("N(< G), whole sky")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "allsky_counts.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 4.5))
    dens = model.lf.density()
    mg = model.lf.mg[:-1] + 0.5 * (model.lf.mg[1] - model.lf.mg[0])
    for k, name in enumerate(model.lf.names):
        if name != "bulge":
            ax.semilogy(mg, np.where(dens[k] > 0, dens[k], np.nan), lw=1, label=name)
    ax.semilogy(mg, dens[[i for i, n in enumerate(model.lf.names) if n != "bulge"]].sum(0), "k", lw=2,
                label="sum at the Sun")
    ax.set_xlabel("M_G [mag]")
    ax.set_ylabel("sources pc^-3 mag^-1 at the Sun")
    ax.set_ylim(1e-8, 1e-1)
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(out / "luminosity_functions.png", dpi=110)
    plt.close(fig)


def _bright_parallax(model, rng, n=300_000):
    """90th percentile and median of parallax and median total proper motion at G = 6-7
    per |b| band, against Hipparcos' (docs/galaxy_model.md)."""
    # more draws from the density than one realisation holds, for stable percentiles
    df = model.sample_cone(0.0, 90.0, 180.0, 6.0, 7.0, rng, max_stars=n, min_draw=n)
    b = np.abs(df["b"].to_numpy())
    rows = []
    for lo, hi in ((0, 10), (10, 30), (30, 60), (60, 90)):
        sel = (b >= lo) & (b < hi)
        plx = df["parallax"].to_numpy()[sel]
        pm = np.hypot(df["pmra"].to_numpy()[sel], df["pmdec"].to_numpy()[sel])
        rows.append(dict(abs_b_lo=lo, abs_b_hi=hi, n=int(sel.sum()),
                         p90_parallax_mas=float(np.percentile(plx, 90)),
                         median_parallax_mas=float(np.median(plx)),
                         median_pm_masyr=float(np.median(pm))))
    return pd.DataFrame(rows)


def _class_figure(path, by_class):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = by_class.dropna(subset=["ratio", "ratio_sigma"])
    fig, ax = plt.subplots(figsize=(7.5, 5))
    x = np.arange(len(ok))
    ax.errorbar(x, np.ones(len(ok)), yerr=ok["ratio_sigma"], fmt="none", color="0.6",
                label="published +- 1 sigma")
    ax.plot(x, ok["ratio"], "ko", label=f"model {MODEL_VERSION}")
    stars = ok["counts"] == "stars"
    ax.plot(x[stars.to_numpy()], ok["ratio_sources"][stars], "o", mfc="none", color="tab:blue",
            label="same, one star per model source")
    ax.axhspan(0.8, 1.2, color="tab:green", alpha=0.15, label="+-20 % target")
    ax.set_xticks(x, [f"{c} ({n})" for c, n in zip(ok["cls"], ok["counts"])], fontsize=7,
                  rotation=30, ha="right")
    ax.set_ylabel("model / published local density")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _fixed(value, digits: int) -> str:
    """``value`` with ``digits`` decimals; empty for NaN (a bin Gaia's bright file does not reach)."""
    return f"{value:.{digits}f}" if np.isfinite(value) else ""


def published_section(out, model, rng):
    """The calibration facts: counts per G vs Tycho-2/UCAC4 and Gaia DR3 (the reference from
    G = 10 on, where the compilation's UCAC4 part is too bright: :mod:`.published_counts`), the
    local LF and censuses (CSV + PNG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    comp = pc.count_comparison(model, range(4, 15))
    comp.to_csv(out / "published_counts.csv", index=False)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    g = comp["G_min"] + 0.5
    ax.errorbar(g, np.ones(len(g)), yerr=comp["rel_uncertainty"], fmt="none", color="0.6",
                label="published +- (G - V syst., Poisson)")
    ax.plot(g, comp["ratio"], "ko-", label=f"model {MODEL_VERSION}")
    if comp["ratio_gaia"].notna().any():  # Gaia DR3's own G counts (optional extra realsky)
        ax.plot(g, comp["ratio_gaia"], "s", color="tab:red", mfc="none",
                label="model / Gaia DR3 (file G < 10, quoted counts G = 10-14)")
    ax.axhspan(0.92, 1.08, color="tab:green", alpha=0.15, label="+-8 % target")
    ax.set_xlabel("G [mag] (1-mag bins)")
    ax.set_ylabel("model / published all-sky count")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "published_counts.png", dpi=110)
    plt.close(fig)

    lf = pc.local_lf_comparison(model)
    lf.to_csv(out / "local_lf.csv", index=False)
    census = pc.local_census_comparison(model)
    census.to_csv(out / "local_census.csv", index=False)
    bright = _bright_parallax(model, rng)
    bright.to_csv(out / "bright_parallax.csv", index=False)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    x = lf["M_G_lo"] + 0.5
    ax.semilogy(x, lf["model"], "ko-", label=f"model {MODEL_VERSION}, all")
    ax.semilogy(x, lf["model_thin_giants"].where(lf["model_thin_giants"] > 0), "s-", color="tab:red",
                label="model, thin-disc giants")
    ax.semilogy(x, lf["bovy_ms"], "D", color="tab:blue", ms=8, mfc="none",
                label="Bovy (2017) main sequence > 1 Msun")
    ax.axhline(pc.BOVY_GIANTS_PC3, color="tab:red", ls=":", label="Bovy (2017) all giants (total)")
    ax.set_xlabel("M_G [mag] (1-mag bins)")
    ax.set_ylabel("sources pc^-3 per bin at the Sun")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "local_lf.png", dpi=110)
    plt.close(fig)
    local = pc.local_sources_within(model)
    by_class = pc.local_density_by_class(model)
    by_class.to_csv(out / "local_density_by_class.csv", index=False)
    _class_figure(out / "local_density_by_class.png", by_class)
    fmt = lambda v: "" if not np.isfinite(v) else f"{v:.3g}"  # noqa: E731
    return [
        "## 5. Calibration facts (docs/galaxy_model.md)", "",
        f"Model version `{MODEL_VERSION}`.", "",
        "| G bin | model | published (Tycho-2/UCAC4, G - V = -0.25) | +- | model / published | Gaia DR3 "
        "| +- | model / Gaia DR3 |",
        "|---|---|---|---|---|---|---|---|",
        *[f"| {c.G_min}-{c.G_min + 1} | {c.model:.4g} | {c.published:.4g} | "
          f"{100 * c.rel_uncertainty:.0f} % | {c.ratio:.2f} | {_fixed(c.gaia_dr3, 0)} | "
          f"{_fixed(100 * c.gaia_rel_uncertainty, 1)}{' %' * bool(np.isfinite(c.gaia_rel_uncertainty))} | "
          f"{_fixed(c.ratio_gaia, 2)} |"
          for c in comp.itertuples()], "",
        "Gaia DR3's counts are the reference: below G = 10 the bundled file (extra `realsky`), at "
        "G = 10-14 the quoted cumulative counts; the compilation's UCAC4 part (G >= 10) is 1.13-1.28 x "
        "too high (docs/galaxy_model.md).", "",
        f"- sources with M_G < {pc.GCNS_MG_LIMIT} within 100 pc: model **{local:.0f}**, GCNS "
        f"{pc.GCNS_WITHIN_100PC:.0f} +- {pc.GCNS_SYST:.0f} (ratio {local / pc.GCNS_WITHIN_100PC:.2f}; "
        "the calibration, not a check)",
        "", "![published counts](published_counts.png)", "",
        "### Local luminosity function per 1-mag M_G bin (sources pc^-3 at the Sun)", "",
        "The GCNS and CNS5 luminosity functions per bin were not found in the sources "
        "searched (docs/galaxy_model.md); Bovy (2017) covers the main sequence above 1 Msun "
        "(M_G ~ 1.5-4.3).", "",
        "| M_G bin | model, all | model, thin-disc giants | model, the rest | Bovy 2017 MS | rest / Bovy |",
        "|---|---|---|---|---|---|",
        *[f"| {r.M_G_lo}-{r.M_G_lo + 1} | {r.model:.3g} | {r.model_thin_giants:.3g} | {r.model_dwarfs:.3g} | "
          f"{fmt(r.bovy_ms)} | {fmt(r.ratio_to_bovy)} |" for r in lf.itertuples()], "",
        "![local LF](local_lf.png)", "",
        "### Local density per spectral class (stars or sources pc^-3 at the Sun)", "",
        "Mamajek's compilation of volume-complete samples (Hipparcos-2, RECONS 10 pc), "
        "Holberg et al. (2002) for white dwarfs, and the CNS5 within 25 pc (Golovin et al. "
        "2023: M dwarfs as its published share of its star density) (published_counts.py); "
        "each class spans the M_G range of its dwarf subtypes. Samples of component stars "
        "are compared with the model's sources x (1 + multiplicity frequency); the last "
        "column gives the other reading (one star per source). Target: within 20 %.", "",
        "| class | M_G range | counts | published | +- | model | model / published "
        "| same, one star per source | sample |",
        "|---|---|---|---|---|---|---|---|---|",
        *[f"| {r.cls} | {fmt(r.M_G_lo)}-{fmt(r.M_G_hi)} | {r.counts} | {r.published:.3g} | "
          f"{fmt(r.uncertainty)} | {fmt(r.model)} | {fmt(r.ratio)} | {fmt(r.ratio_sources)} | {r.sample} |"
          for r in by_class.itertuples()], "",
        "The model has no white-dwarf population: the Wielen/Allen bins its faint dwarfs "
        "come from count the white dwarfs among the stars of their M_V, so they sit in the "
        "M-dwarf range (the 'M + white dwarfs' row). At G < 20 this changes little for the "
        "prior: white dwarfs (M_G ~ 10-16) lie at the distances and have the old-disc "
        "kinematics of M dwarfs of the same M_G, and they are ~7 % of the stars in that range.", "",
        "![local density by class](local_density_by_class.png)", "",
        "### Local content against independent censuses", "",
        "| quantity | published | +- (Poisson) | model | model / published |", "|---|---|---|---|---|",
        *[f"| {r.quantity} | {r.published:.4g} | {r.uncertainty:.2g} | {r.model:.4g} | {r.ratio:.2f} |"
          for r in census.itertuples()], "",
        "White dwarfs are not a separate population in the model (they sit in the Wielen/Allen "
        f"bins at M_V = 11-16); GCNS 60 pc holds {pc.GCNS60_WHITE_DWARFS}, CNS5 25 pc "
        f"{pc.CNS5_25PC['white_dwarfs']}.", "",
        "### Parallaxes of the bright stars, G = 6-7 (before the calibration the model's 90th "
        "percentile was 0.71-0.82 of the real one in each band)", "",
        "| abs(b) [deg] | stars drawn (from the density) | 90th percentile parallax [mas] "
        "| median parallax [mas] | median total proper motion [mas/yr] |",
        "|---|---|---|---|---|",
        *[f"| {r.abs_b_lo}-{r.abs_b_hi} | {r.n} | {r.p90_parallax_mas:.1f} | {r.median_parallax_mas:.2f} "
          f"| {r.median_pm_masyr:.1f} |" for r in bright.itertuples()], "",
    ]


def _report(out, beam, mu_plx_sky, cells, counts, published, extra=()):
    exp, by_pop, n_drawn, mu_plx, variants = beam
    lo, hi = GUMS_BEAM_COUNT * (1 - BEAM_TOLERANCE), GUMS_BEAM_COUNT * (1 + BEAM_TOLERANCE)
    r = cells["ratio"]
    frac = float(((r >= RATIO_RANGE[0]) & (r <= RATIO_RANGE[1])).mean())
    frac_fn = float(((r >= FOOTNOTE_RANGE[0]) & (r <= FOOTNOTE_RANGE[1])).mean())
    worst = cells.assign(dev=np.abs(np.log10(r / 0.65))).nlargest(10, "dev")
    ok = lambda c: "PASS" if c else "FAIL"  # noqa: E731
    lines = [
        "# Validation of the built-in galaxy model", "",
        "Generated by `python -m mcsweep.validation.population_validation`. Model parameters: defaults "
        "(`conf/population/galaxy_model.yaml`).", "",
        "## 1. Paper Table 1 beam (l, b) = (245.7, +46.5) deg, r = 1 deg, G = 15 +- 0.5", "",
        f"- expected sources: **{exp:.0f}** (GUMS: {GUMS_BEAM_COUNT}; accepted {lo:.0f}-{hi:.0f}) "
        f"-> {ok(lo <= exp <= hi)} ({100 * (exp / GUMS_BEAM_COUNT - 1):+.0f} %)",
        "- by population: " + ", ".join(f"{k} {v:.0f}" for k, v in by_pop.items()),
        f"- one Poisson draw: {n_drawn} stars", "",
        "| variant | expected |", "|---|---|",
        *[f"| {k} | {v:.0f} |" for k, v in variants.items()], "",
        "## 2. Median proper motion / parallax at G = 15", "",
        f"- Table 1 beam: **{mu_plx:.1f} /yr**; whole sky, G = 14.5-15.5: **{mu_plx_sky:.1f} /yr** "
        f"(GUMS about 10 /yr; accepted {MU_PLX_RANGE[0]:g}-{MU_PLX_RANGE[1]:g}) -> "
        f"{ok(MU_PLX_RANGE[0] <= mu_plx <= MU_PLX_RANGE[1] and MU_PLX_RANGE[0] <= mu_plx_sky <= MU_PLX_RANGE[1])}", "",
        "## 3. sigma_F90 / 90th percentile of parallax (48 HEALPix nside=2 galactic nested "
        "centres x G = 6..20)", "",
        f"- fraction of the {len(cells)} cells with ratio in {RATIO_RANGE[0]}-{RATIO_RANGE[1]}: "
        f"**{frac:.2f}**; in the footnote's {FOOTNOTE_RANGE[0]}-{FOOTNOTE_RANGE[1]}: **{frac_fn:.2f}**",
        f"- median ratio {r.median():.2f}; 10-90 % range {r.quantile(0.1):.2f}-{r.quantile(0.9):.2f}",
        "- median ratio per G: " + ", ".join(f"{g}: {v:.2f}" for g, v in cells.groupby("G")["ratio"].median().items()),
        "", "Worst cells (largest |log10(ratio / 0.65)|):", "",
        "| l | b | G | radius | p90 [mas] | sigma_F90 [mas] | ratio |", "|---|---|---|---|---|---|---|",
        *[f"| {w.l_deg:.1f} | {w.b_deg:.1f} | {w.G} | {w.radius_deg:.1f} | {w.p90_parallax_mas:.3g} | "
          f"{w.sigma_f90_mas:.3g} | {w.ratio:.2f} |" for w in worst.itertuples()], "",
        "![ratio](ratio_sigma_f90_p90.png)", "",
        "## 4. All-sky counts", "",
        "| G bin | model sources | thin | thick | halo | bulge |", "|---|---|---|---|---|---|",
        *[f"| {c.G_min}-{c.G_max} | {c.total:.3g} | {c.thin_disc:.3g} | {c.thick_disc:.3g} | "
          f"{c.halo:.3g} | {c.bulge:.3g} |" for c in counts.itertuples()], "",
        "| published | value | model | model / published |", "|---|---|---|---|",
        *[f"| {name} | {value:.4g} | {mod:.4g} | {mod / value:.2f} |" for name, cut, value, mod in published],
        "", "Gaia DR3 and DR2 totals include sources fainter than G = 20 where the catalogues "
        "are incomplete (EDR3 is essentially complete for 12 < G < 17) and non-stellar "
        "sources; GUMS-10 is the closer comparison for the paper.", "",
        "![counts](allsky_counts.png)", "", "![lf](luminosity_functions.png)", "",
        *extra,
    ]
    (out / "report.md").write_text("\n".join(lines))
    return frac, frac_fn


def main(argv=None):
    """Command-line entry point (see the module docstring)."""
    ap = argparse.ArgumentParser(description="Validate mcsweep's built-in galaxy model.")
    ap.add_argument("--out", default="results/population_validation", help="output directory")
    ap.add_argument("--seed", type=int, default=20150821)
    ap.add_argument("--sky-stars", type=int, default=200_000,
                    help="stars drawn over the whole sky for the median mu/parallax")
    args = ap.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        if not os.access(out, os.W_OK):
            raise PermissionError(errno.EACCES, "not writable")
    except OSError as exc:
        # before the model is built and drawn from, not in a traceback after it
        print(f"population_validation: --out={args.out!r} is not accepted ({exc.strerror}); expected a "
              "writable directory", file=sys.stderr)
        return 2
    rng = np.random.default_rng(args.seed)
    model = GalaxyModel()
    beam = _beam_section(model, rng)
    counts, mu_plx_sky, published = _sky_section(model, rng, args.sky_stars)
    cells = ratio_table(model, rng)
    cells.to_csv(out / "ratio_cells.csv", index=False)
    counts.to_csv(out / "counts.csv", index=False)
    _figures(out, cells, counts, published, model)
    extra = published_section(out, model, rng)
    frac, frac_fn = _report(out, beam, mu_plx_sky, cells, counts, published, extra)
    print(f"Table 1 beam: {beam[0]:.0f} expected (GUMS {GUMS_BEAM_COUNT}); "
          f"median mu/plx beam {beam[3]:.1f}, sky {mu_plx_sky:.1f} /yr; "
          f"ratio in {RATIO_RANGE}: {frac:.2f} of cells (footnote range: {frac_fn:.2f}); "
          f"report: {out / 'report.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
