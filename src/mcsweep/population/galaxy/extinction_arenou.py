"""Structured extinction near the Sun: the 3-D model of Arenou, Grenon & Gomez (1992).

Arenou, Grenon & Gomez (1992, A&A 258, 104; "AGG92") fitted the visual extinction of
stars with MK types and photometry in 199 cells of Galactic (l, b). Per cell the
Appendix gives alpha, beta, gamma, r0 and the relative uncertainty of A_V, with (r in kpc)

    A_V(r) = alpha r + beta r^2                        for r <= r0   (Eq. 5)
    A_V(r) = alpha r0 + beta r0^2 + gamma (r - r0)     for r >  r0   (Eq. 5bis).

The coefficients are in ``population/data/arenou1992.csv`` (header: where they were read
and which entries are doubtful). A_G = A_V x :data:`.extinction.AG_OVER_AV`
(Wang & Chen 2019), the factor the dust disc uses.

Checks of the table (``tests/population/test_extinction_arenou.py``):

* the cells tile the sky exactly once: 11 latitude bands (-90, -60, -45, -30, -15, -5, 5,
  15, 30, 45, 60, 90 deg), each split into 9-36 longitude intervals covering 0-360 deg;
* r0 is one of three things in all 199 cells: the vertex -alpha / (2 beta) of the parabola
  rounded to 1 pc (123 cells; A_V is flat from there on unless gamma > 0), the band's
  largest distance (45 cells, below), or the distance where A_V reaches a round value
  (0.10 mag in the 12 cells at b < -60 deg and 5 at b > 60 deg; 2.00 mag in 3 plane
  cells, one with beta > 0) -- except 12 cells (9 with beta > 0, 3 with the vertex beyond
  r0) where A_V(r0) is 0.13-3.09 mag. Because r0 is the rounded vertex, A_V may dip by < 1e-6 mag just before r0; the
  model takes the running maximum along each sight line (a cumulative extinction cannot
  decrease) and clips the small negative values that negative alpha gives near the Sun;
* the band's largest r0 equals 0.2 kpc / sin|b_mid| (b_mid the band's middle latitude;
  1.152, 0.523, 0.329, 0.252, 0.207 kpc to the table's 3 digits) and 2.000 kpc in the
  |b| < 5 deg band: the paper's fits reach |z| = 200 pc, and 2 kpc in the plane
  (:func:`validity_limit_kpc`);
* doubtful entries (transcription; the printed Appendix was not reachable): beta = +7.71159
  at b = 5-15, l = 10-30 deg (Aquila Rift / Ophiuchus direction) gives A_V = 2.05 mag at
  r0 = 355 pc, twice the neighbouring cells (0.9-1.0 mag). Kept: with -7.71159 the
  parabola's vertex would be at 198 pc and A_V would fall from 0.30 to 0.11 mag between
  198 and 355 pc, impossible for a cumulative extinction; +7.71159 is the only sign
  consistent with the listed r0 (and a steep rise is plausible towards the dark clouds of
  that direction, the Aquila Rift and Ophiuchus). beta = 11.69217 (b = 15-30, l = 180-200; another copy 11.6917) and alpha =
  2.22534 (b = -90..-60, l = 0-29; another copy 2.22538): the two readings differ by
  < 1e-5 mag, immaterial.

Joining the smooth disc (:class:`ArenouDust`): beyond the cell's validity limit
:func:`validity_limit_kpc` (the data of the fit end there) the extinction grows by the
exponential disc's increment, ``A(d) = A_AGG92(d_lim) + A_disc(d) - A_disc(d_lim)``;
within it AGG92 alone (its gamma included). At high latitude the disc adds little beyond
|z| = 200 pc from the Sun (11-18 % of its column on either side, < 0.02 mag), in the plane it carries
the extinction to the distant stars (G = 17-20) that AGG92's data never reached. AGG92's
gamma (0-0.37 mag/kpc; 0 in 16 of the 36 plane cells) was fitted to stars within the limit
and would leave the distant disc almost transparent; the disc's 0.7 mag/kpc at the solar radius is the
published local mean (Sharma et al. 2011).
"""

from __future__ import annotations

from functools import lru_cache
from importlib import resources

import numpy as np

from .extinction import AG_OVER_AV, DustModel

__all__ = [
    "ARENOU_TABLE_FILE",
    "ARENOU_BAND_EDGES_DEG",
    "PLANE_LIMIT_KPC",
    "Z_LIMIT_KPC",
    "load_arenou_table",
    "cell_index",
    "av_arenou",
    "validity_limit_kpc",
    "ArenouDust",
]

_DATA = "mcsweep.population.data"
ARENOU_TABLE_FILE = "arenou1992.csv"
#: Latitude band edges of the AGG92 cells, deg.
ARENOU_BAND_EDGES_DEG = (-90.0, -60.0, -45.0, -30.0, -15.0, -5.0, 5.0, 15.0, 30.0, 45.0, 60.0, 90.0)
#: Largest r0 of the |b| < 5 deg cells (AGG92 Appendix), kpc.
PLANE_LIMIT_KPC = 2.0
#: |z| reached by the largest r0 of every other band (0.2 / sin|b_mid|, AGG92 Appendix), kpc.
Z_LIMIT_KPC = 0.2
_COLUMNS = ("b_min", "b_max", "l_min", "l_max", "alpha", "beta", "gamma", "r0_kpc", "sigma_pct")


@lru_cache(maxsize=1)
def load_arenou_table():
    """The 199 AGG92 cells as a dict of float arrays (columns of ``arenou1992.csv``),
    rows ordered by latitude band, then longitude."""
    text = resources.files(_DATA).joinpath(ARENOU_TABLE_FILE).read_text()
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    if tuple(lines[0].split(",")) != _COLUMNS:
        raise ValueError(f"{ARENOU_TABLE_FILE}: expected the columns {_COLUMNS}")
    body = np.array([ln.split(",") for ln in lines[1:]], dtype=float)
    table = {name: body[:, i] for i, name in enumerate(_COLUMNS)}
    for v in table.values():
        v.setflags(write=False)
    return table


@lru_cache(maxsize=1)
def _lookup_keys():
    t = load_arenou_table()
    edges = np.asarray(ARENOU_BAND_EDGES_DEG)
    band = np.searchsorted(edges, t["b_min"], side="right") - 1
    keys = band * 360.0 + t["l_min"]
    if np.any(np.diff(keys) <= 0):
        raise ValueError(f"{ARENOU_TABLE_FILE}: rows not ordered by band and longitude")
    return keys


def cell_index(l_deg, b_deg):
    """Row of the AGG92 table holding each direction (vectorised; l modulo 360, b in
    [-90, 90], b = 90 in the last band)."""
    l = np.mod(np.asarray(l_deg, float), 360.0)
    b = np.asarray(b_deg, float)
    edges = np.asarray(ARENOU_BAND_EDGES_DEG)
    band = np.clip(np.searchsorted(edges, b, side="right") - 1, 0, edges.size - 2)
    return np.searchsorted(_lookup_keys(), band * 360.0 + l, side="right") - 1


def av_arenou(l_deg, b_deg, r_kpc):
    """A_V [mag] of AGG92 Eqs. 5 / 5bis at distance ``r_kpc`` (kpc), negative values
    clipped to 0. ``l_deg, b_deg`` of shape (...,) broadcast against ``r_kpc`` of shape
    (..., n) after a trailing axis is added to the directions."""
    t = load_arenou_table()
    i = cell_index(l_deg, b_deg)[..., None]
    a, bt, g, r0 = t["alpha"][i], t["beta"][i], t["gamma"][i], t["r0_kpc"][i]
    r = np.asarray(r_kpc, float)
    rc = np.minimum(r, r0)
    av = a * rc + bt * rc ** 2 + g * np.maximum(r - r0, 0.0)
    return np.maximum(av, 0.0)


def validity_limit_kpc(b_deg):
    """Distance to which the AGG92 cell of latitude ``b_deg`` holds, kpc: 2 kpc in the
    |b| < 5 deg band, else 0.2 kpc / sin|b_mid| of the band (module notes)."""
    b = np.asarray(b_deg, float)
    edges = np.asarray(ARENOU_BAND_EDGES_DEG)
    band = np.clip(np.searchsorted(edges, b, side="right") - 1, 0, edges.size - 2)
    lo, hi = edges[band], edges[band + 1]
    mid = np.abs(0.5 * (lo + hi))
    with np.errstate(divide="ignore"):
        lim = Z_LIMIT_KPC / np.sin(np.radians(mid))
    return np.where(lo * hi < 0, PLANE_LIMIT_KPC, lim)


class ArenouDust:
    """AGG92 extinction near the Sun joined to a :class:`.extinction.DustModel` beyond it.

    Parameters
    ----------
    disc : DustModel
        The smooth disc whose increment carries A_G beyond the AGG92 validity limit;
        ``disc.av_per_kpc == 0`` does not switch AGG92 off (use no extinction instead).
    ag_over_av : float
        A_G / A_V applied to AGG92's A_V.
    """

    def __init__(self, disc: DustModel, *, ag_over_av=AG_OVER_AV):
        self.disc = disc
        self.ag_over_av = float(ag_over_av)

    def a_g(self, l_deg, b_deg, x, y, z, d_kpc):
        """Cumulative A_G along sight lines.

        Parameters
        ----------
        l_deg, b_deg : ndarray, shape (...,)
            Directions of the sight lines, Galactic, deg.
        x, y, z : ndarray, shape (..., n)
            Galactocentric positions (kpc) of the sample points (for the disc).
        d_kpc : ndarray, shape (n,)
            Heliocentric distances of the sample points, kpc, increasing, first > 0.

        Returns
        -------
        ndarray, shape (..., n)
            A_G in mag from the Sun to each sample point.
        """
        d = np.asarray(d_kpc, float)
        lim = validity_limit_kpc(b_deg)[..., None]                        # (..., 1)
        near = np.minimum(d, lim)                                        # (..., n)
        av = np.maximum.accumulate(av_arenou(l_deg, b_deg, near), axis=-1)
        disc = self.disc.a_g(x, y, z, d)                                 # (..., n)
        # the disc's A_G at the limit, linear between the two bracketing sample points
        j = np.clip(np.searchsorted(d, lim[..., 0]), 1, d.size - 1)[..., None]
        d0, d1 = d[j - 1], d[j]
        a0 = np.take_along_axis(disc, j - 1, axis=-1)
        a1 = np.take_along_axis(disc, j, axis=-1)
        t = np.clip((lim - d0) / (d1 - d0), 0.0, 1.0)
        disc_lim = a0 + t * (a1 - a0)
        beyond = np.where(d > lim, np.maximum(disc - disc_lim, 0.0), 0.0)
        return self.ag_over_av * av + beyond
