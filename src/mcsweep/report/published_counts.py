"""Published facts about the real sky that the built-in galaxy model is calibrated to.

Issue #14; the table with sources and the before/after comparison is in
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
* Faint end: GUMS-10 holds 1.1e9 sources with G < 20 (Robin et al. 2012, A&A 543,
  A100) [V] (a model, the paper's); Gaia DR3 holds 1 811 709 771 sources to G ~ 21
  (Gaia Collaboration, Vallenari et al. 2023, A&A 674, A1) [V], incomplete beyond
  G ~ 20, so a model must hold at least as many with G < 21.
* Local density: the Gaia Catalogue of Nearby Stars (Gaia Collaboration, Smart et al.
  2021, A&A 649, A6) [V abstract] holds 331 312 objects, about 9 % of them beyond
  100 pc, at least 92 % complete down to M9 (M_G ~ 15.5 at 100 pc): 301 500 +- 27 000
  sources within 100 pc (the 9 % contamination taken as the systematic).
* Paper Table 1 beam: 458 GUMS stars (Michalik et al. 2015); Poisson +-21.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

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
    "count_comparison",
    "local_sources_within",
]

#: (V-like magnitude m, N(< m) over the whole sky): Tycho-2 + UCAC4 [S].
TYCHO_UCAC4_CUMULATIVE = (
    (0, 3), (1, 14), (2, 55), (3, 191), (4, 558), (5, 1744), (6, 5326), (7, 16503),
    (8, 48559), (9, 139375), (10, 382925), (11, 1048084), (12, 2955951), (13, 7346735),
    (14, 17214116), (15, 39387795), (16, 88896114),
)
#: Mean G - V of bright stars and its uncertainty, mag (Riello et al. 2021) [M].
G_MINUS_V, G_MINUS_V_SYST = -0.25, 0.10
#: GCNS sources within 100 pc and systematic (see module notes).
GCNS_WITHIN_100PC = 331_312 * (1 - 0.09)
GCNS_SYST = 0.09 * 331_312
#: Absolute magnitude to which GCNS is complete at 100 pc (M9 dwarfs, G ~ 20.5) [M].
GCNS_MG_LIMIT = 15.5
GUMS_G20 = 1.1e9
DR3_TOTAL = 1_811_709_771


def _cum(m):
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
    out = _cum(hi) - _cum(g_lo - g_minus_v)
    return np.where(hi <= TYCHO_UCAC4_CUMULATIVE[-1][0], out, np.nan)


def count_comparison(model, g_bins=range(4, 20)):
    """Model all-sky counts per 1-mag G bin next to the published ones (DataFrame).

    Columns: ``G_min``, ``model``, ``published``, ``published_lo``/``_hi`` (G - V
    +- its systematic), ``ratio``, ``rel_uncertainty`` (systematic and Poisson of the
    published count added in quadrature).
    """
    rows = []
    for g in g_bins:
        n = model.expected_count(0.0, 90.0, 180.0, g, g + 1)
        pub = float(published_counts_per_g(g))
        lo = float(published_counts_per_g(g, G_MINUS_V - G_MINUS_V_SYST))
        hi = float(published_counts_per_g(g, G_MINUS_V + G_MINUS_V_SYST))
        rel = np.hypot(0.5 * abs(hi - lo) / pub, 1.0 / np.sqrt(pub)) if np.isfinite(pub) else np.nan
        rows.append(dict(G_min=g, model=n, published=pub, published_lo=min(lo, hi),
                         published_hi=max(lo, hi), ratio=n / pub, rel_uncertainty=rel))
    return pd.DataFrame(rows)


def local_sources_within(model, radius_pc=100.0, mg_max=GCNS_MG_LIMIT):
    """Sources with M_G < mg_max in a sphere of ``radius_pc`` around the Sun.

    Uses the components' luminosity functions at the Sun (the bulge excluded); the
    vertical fall-off of the discs within 100 pc (a few per cent) is neglected.
    """
    keep = [i for i, n in enumerate(model.lf.names) if n != "bulge"]
    dens = float(np.interp(mg_max, model.lf.mg, model.lf.cdf[keep].sum(axis=0)))
    return dens * 4.0 / 3.0 * np.pi * radius_pc ** 3
