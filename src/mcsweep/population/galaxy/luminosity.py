"""Luminosity functions in absolute G magnitude, one per stellar component.

Method (a justified simplification of the Besancon population synthesis):

1. The local luminosity function at the Sun, in three parts, each calibrated to published
   local densities (docs/galaxy_model.md):

   * giants: the Wielen (1974) bins with M_V <= 1 (as tabulated in Allen's Astrophysical
     Quantities; ``data/lf_wielen_allen.ecsv``; :data:`.parameters.GIANT_MV_MAX`) scaled
     to the local giant density of Bovy (2017), :data:`.parameters.LOCAL_GIANT_DENSITY_PC3`;
   * bright dwarfs, M_V < 4.5 (above ~1 Msun): Bovy's (2017) present-day mass function
     dn/dM = 0.016 M^-4.7 pc^-3 Msun^-1 integrated over each bin's mass range
     (:data:`.parameters.BOVY_PDMF_NORM`);
   * fainter dwarfs: the Wielen/Allen bins times ``faint_scale``, which the model sets
     from the Gaia Catalogue of Nearby Stars (:mod:`.model`).

   Bovy's numbers and the GCNS count sources (unresolved systems count once).
2. The local stars of each magnitude bin are shared among the components present at
   the Sun in proportion to the weight

   * dwarfs:  w_p(M) = rho_p / mu_p * xi_p(m(M)) * s_p(M),
   * giants:  w_p    = rho_p / mu_p * < xi_p(m_TO(t)) |dm_TO/dt| >_ages,

   where rho_p is the component's mass density at its reference point (Robin et al.
   2003), xi_p its IMF, mu_p = int m xi_p dm the living mass per unit IMF normalisation,
   m(M) the mass of a dwarf of magnitude M (Pecaut & Mamajek 2013 sequence), s_p the
   fraction of the component's ages at which that dwarf is still on the main sequence,
   and m_TO(t) the turn-off mass at age t (t_MS ~ m^-2.5). The giant weight is the rate
   at which stars leave the main sequence, so old populations get fewer giants per unit
   mass than young ones. Because the common factor |dm/dM| cancels, the components'
   luminosity functions add up exactly to phi(M_V) at the Sun.
3. The bulge, absent at the Sun, gets the same weights with its central density.
4. M_V becomes M_G with the dwarf sequence's G - V (Mamajek's table) and G - V = -0.31
   for giants. The dwarfs of the old metal-poor thick disc and halo are shifted so their
   turn-off lies at M_V = 4.0 (globular-cluster turn-offs, Newby et al. 2011).
5. Optionally (``subgiants=True``; the galaxy model's ``subgiants``), stars off the main
   sequence at 1.5 < M_V < 4.5 (the bins centred on 2, 3 and 4): where Bovy's main
   sequence replaces the Wielen/Allen bins, what the Wielen/Allen function (all stars)
   holds beyond it (:func:`subgiant_lf`). They are evolved stars, shared among the
   components like the giants (the rate of leaving the main sequence; in the thin disc
   they live in the giant-only companions, so ``giant_thickness_factor`` sets their
   heights and velocities too) with G - V of G5V (:data:`.parameters.SUBGIANT_G_MINUS_V`).
   Without them the model has no stars between the main sequence and the giants' bins,
   where Hipparcos (van Leeuwen 2007) holds a fifth of its G = 6-7 stars at M_G = 1-4
   (docs/galaxy_model.md).
6. With ``evolved_stars="parsec"`` (the galaxy model's default since besancon-r03-6), items
   1-5's giants, their early-type main-sequence share and the subgiants are replaced:

   * every evolved star comes from the isochrones of its component's ages and metallicities
     (:mod:`.evolved`), rho_p / mu_p xi_p(m) dm per isochrone row, at the row's M_G: its
     luminosity function and its number against the dwarfs follow from the same mass
     budget and IMF, with no local giant density imposed (Bovy's 3.9e-4 pc^-3 becomes a
     check, docs/galaxy_colours.md);
   * the main sequence above 1 Msun, the bins with M_V <= GIANT_MV_MAX included, is Bovy's
     (2017) present-day mass function, shared among the components like the other dwarfs;
   * a thin-disc dwarf is on the main sequence while its mass is below the isochrones'
     turn-off at its component's age and mean metallicity (:func:`.evolved.turnoff_mass`),
     not the textbook t ~ m^-2.5, which keeps A stars of 2 Msun alive for 1.8 Gyr instead
     of the isochrones' 1.1 Gyr, i.e. in older, thicker discs; rho / mu takes the same
     turn-off (the metal-poor components keep item 4's);
   * ``subgiants=False`` leaves out the isochrones' subgiant branch.

   The thin disc's evolved stars stay in the giant-only companions of the age bins, whose
   thickness is ``giant_thickness_factor``.

Data files are read lazily on first use via :mod:`importlib.resources`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np
from astropy.table import Table

from . import parameters as P
from .evolved import load_evolved_isochrones, row_weights
from .evolved import turnoff_mass as isochrone_turnoff_mass

__all__ = [
    "LuminosityTable",
    "load_local_lf",
    "load_dwarf_sequence",
    "imf",
    "turnoff_mass",
    "local_dwarf_lf",
    "subgiant_lf",
    "build_luminosity_table",
    "build_part_table",
    "dwarf_shift",
    "PARTS",
    "EVOLVED_STARS",
    "evolved_lf",
    "stars_per_imf_unit",
    "isochrone_dwarf_weights",
]

_DATA = "mcsweep.population.data"
#: Spacing of the absolute-magnitude grid of the tabulated CDFs, mag.
MG_STEP = 0.05
MG_MIN, MG_MAX = -9.0, 22.0


@lru_cache(maxsize=1)
def load_local_lf():
    """Local luminosity function: (M_V bin centres [mag], phi [stars pc^-3 mag^-1])."""
    with resources.files(_DATA).joinpath("lf_wielen_allen.ecsv").open("r") as fh:
        t = Table.read(fh.read(), format="ascii.ecsv")
    return np.asarray(t["M_V"], float), np.asarray(t["phi"], float) * 1e-4


@lru_cache(maxsize=1)
def load_dwarf_sequence():
    """Dwarf sequence: (M_V [mag], G - V [mag], mass [Msun]), M_V increasing."""
    with resources.files(_DATA).joinpath("dwarf_sequence_mamajek.ecsv").open("r") as fh:
        t = Table.read(fh.read(), format="ascii.ecsv")
    return (np.asarray(t["M_V"], float), np.asarray(t["G_minus_V"], float),
            np.asarray(t["mass"], float))


def imf(m, pieces):
    """Broken power-law IMF dN/dm, continuous at the breaks and equal to 1 at 1 Msun.

    Parameters
    ----------
    m : array_like
        Mass, Msun.
    pieces : tuple of (m_break, alpha)
        dN/dm ~ m^-alpha below each break (breaks increasing, the last one ``inf``).

    Returns
    -------
    ndarray
        dN/dm in units of its value at 1 Msun.
    """
    m = np.asarray(m, float)
    edges = [0.0] + [b for b, _ in pieces]
    logc = [0.0]
    for i in range(1, len(pieces)):
        m_b = pieces[i - 1][0]
        logc.append(logc[-1] + (pieces[i][1] - pieces[i - 1][1]) * np.log(m_b))
    i_one = next(i for i in range(len(pieces)) if edges[i] <= 1.0 < edges[i + 1])
    out = np.zeros_like(m)
    for i, (_, alpha) in enumerate(pieces):
        sel = (m >= edges[i]) & (m < edges[i + 1])
        out[sel] = np.exp(logc[i] - logc[i_one]) * m[sel] ** (-alpha)
    return out


def turnoff_mass(age_gyr):
    """Main-sequence turn-off mass (Msun) at a given age (Gyr)."""
    return (np.asarray(age_gyr, float) / P.MS_LIFETIME_SUN_GYR) ** (-1.0 / P.MS_LIFETIME_SLOPE)


def _mass_integrals(comp, m_up):
    m = np.geomspace(P.MASS_MIN_MSUN, m_up, 4001)
    xi = imf(m, comp.imf)
    number = np.trapezoid(xi, m)
    mass = np.trapezoid(m * xi, m)
    return number, mass


def _ages(comp, n=400):
    a, b = comp.age_gyr
    if b <= a:
        return np.array([a])
    return np.linspace(max(a, 0.02), b, n)


def mass_of_mv(mv):
    """Mass [M_sun] of a main-sequence star of absolute magnitude ``mv`` (the dwarf sequence)."""
    seq_mv, _, seq_m = load_dwarf_sequence()
    return 10.0 ** np.interp(mv, seq_mv, np.log10(seq_m))


def _g_minus_v(mv):
    seq_mv, seq_gv, _ = load_dwarf_sequence()
    return np.interp(mv, seq_mv, seq_gv)


def _mv_of_mass(m):
    seq_mv, _, seq_m = load_dwarf_sequence()
    # mass decreases with M_V: interpolate on the reversed arrays
    return np.interp(np.log10(m), np.log10(seq_m[::-1]), seq_mv[::-1])


def stars_per_imf_unit(comp, *, isochrone_turnoff=False):
    """rho / mu of ``comp``: its stars per pc^3 at its reference point per unit of the IMF's
    normalisation (:func:`imf`, 1 at 1 Msun); the living mass up to the turn-off at the mean
    age sets it (R03's mass densities), the bulge's star density (R03 Table 5) for the bulge.
    The turn-off is :func:`turnoff_mass`'s, or with ``isochrone_turnoff`` the isochrones'
    at the component's mean metallicity (:func:`.evolved.turnoff_mass`)."""
    ages = _ages(comp)
    t = np.mean(ages)
    m_up = float(_isochrone_turnoff(comp, t) if isochrone_turnoff else turnoff_mass(t))
    number, mass = _mass_integrals(comp, m_up)
    if comp.law == "bulge":
        return P.BULGE_N0_PER_PC3 / number
    return comp.rho_ref / mass


def component_weights(comp, dwarf_mv, n_sub=20):
    """(dwarf weights per bin, giant weight) of one component."""
    ages = _ages(comp)
    rho_over_mu = stars_per_imf_unit(comp)

    def alive(m_sub):
        t_ms = P.MS_LIFETIME_SUN_GYR * m_sub ** (-P.MS_LIFETIME_SLOPE)
        return (t_ms[..., None] > ages[None, None, :]).mean(axis=-1)

    w_dwarf = _dwarf_weights(comp, dwarf_mv, alive, rho_over_mu, n_sub)
    # giants: rate at which stars leave the main sequence, averaged over ages
    m_to = turnoff_mass(ages)
    rate = imf(m_to, comp.imf) * m_to / (P.MS_LIFETIME_SLOPE * ages)
    w_giant = rho_over_mu * float(np.mean(rate))
    return w_dwarf, w_giant


def _isochrone_turnoff(comp, age_gyr):
    """The turn-off mass of ``comp``'s dwarfs at ``age_gyr``: the isochrones' at its mean
    metallicity, except for the old metal-poor components, whose dwarfs sit on the solar
    sequence shifted by :func:`dwarf_shift` so that the textbook turn-off lands at the observed
    M_V (item 4): their main sequence must end where that shift was made."""
    if comp.metal_poor:
        return turnoff_mass(age_gyr)
    return isochrone_turnoff_mass(age_gyr, comp.feh[0])


def isochrone_dwarf_weights(comp, dwarf_mv, n_sub=20):
    """The dwarf weights per bin of :func:`component_weights`, with a star on the main
    sequence while its mass is below the isochrones' turn-off at the component's mean
    metallicity (:func:`.evolved.turnoff_mass`; :func:`_isochrone_turnoff`) instead of the
    textbook lifetime, and rho / mu with that turn-off (module notes, item 6)."""
    m_to = _isochrone_turnoff(comp, _ages(comp))

    def alive(m_sub):
        return (m_sub[..., None] < m_to[None, None, :]).mean(axis=-1)

    return _dwarf_weights(comp, dwarf_mv, alive, stars_per_imf_unit(comp, isochrone_turnoff=True), n_sub)


def _dwarf_weights(comp, dwarf_mv, alive, rho_over_mu, n_sub):
    """rho / mu x the IMF x the fraction of the component's ages at which the dwarf is still on
    the main sequence (``alive(masses)``), averaged over ``n_sub`` points of each 1-mag bin."""
    sub = dwarf_mv[:, None] + (np.arange(n_sub) + 0.5)[None, :] / n_sub - 0.5
    m_sub = mass_of_mv(sub)
    return rho_over_mu * (imf(m_sub, comp.imf) * alive(m_sub)).mean(axis=1)


@dataclass(frozen=True)
class LuminosityTable:
    """Cumulative luminosity functions in M_G of all components at their reference point.

    Attributes
    ----------
    names : tuple of str
        Component names, in the order of the rows of ``cdf``.
    mg : ndarray, shape (K,)
        Absolute G magnitude grid, mag (increasing, spacing :data:`MG_STEP`).
    cdf : ndarray, shape (n_comp, K)
        Number of stars per pc^3 brighter than ``mg`` at the reference point.
    """

    names: tuple
    mg: np.ndarray
    cdf: np.ndarray

    def total(self):
        """Stars per pc^3 of each component at its reference point."""
        return self.cdf[:, -1]

    def density(self):
        """Luminosity function per unit M_G on the grid midpoints, stars pc^-3 mag^-1."""
        return np.diff(self.cdf, axis=1) / MG_STEP


def local_dwarf_lf(faint_scale=1.0, *, bright_end=False):
    """Local main-sequence luminosity function per 1-mag M_V bin (see module notes).

    Parameters
    ----------
    faint_scale : float
        Factor on the Wielen/Allen bins fainter than :data:`.parameters.BOVY_PDMF_MV_MAX`.
    bright_end : bool
        Also the bins with M_V <= :data:`.parameters.GIANT_MV_MAX`, from Bovy's mass
        function like the other bright bins (module notes, item 6): the main sequence
        alone, when the evolved stars come from isochrones.

    Returns
    -------
    mv : ndarray
        Bin centres, mag (M_V > :data:`.parameters.GIANT_MV_MAX` unless ``bright_end``).
    phi : ndarray
        Sources per pc^3 in each bin.
    bright : ndarray of bool
        Bins taken from Bovy's (2017) mass function.
    """
    mv, phi = load_local_lf()
    dwarf = mv > (-np.inf if bright_end else P.GIANT_MV_MAX)
    mv, phi = mv[dwarf], phi[dwarf]
    bright = mv < P.BOVY_PDMF_MV_MAX
    m_hi, m_lo = mass_of_mv(mv - 0.5), mass_of_mv(mv + 0.5)
    a = P.BOVY_PDMF_SLOPE - 1.0
    pdmf = P.BOVY_PDMF_NORM / a * (m_lo ** -a - m_hi ** -a)
    return mv, np.where(bright, pdmf, phi * faint_scale), bright


def subgiant_lf():
    """Local stars off the main sequence per 1-mag M_V bin (module notes, item 5): the
    Wielen/Allen bins (all stars) minus Bovy's main sequence where it replaces them
    (``GIANT_MV_MAX < M_V < BOVY_PDMF_MV_MAX``), clipped at zero.

    Returns
    -------
    mv : ndarray
        Bin centres, mag.
    phi : ndarray
        Stars per pc^3 in each bin.
    """
    mv, phi = load_local_lf()
    dwarf_mv, dwarf_phi, bright = local_dwarf_lf()
    wielen = phi[mv > P.GIANT_MV_MAX][bright]
    return dwarf_mv[bright], np.clip(wielen - dwarf_phi[bright], 0.0, None)


def evolved_lf(comp, mg_edges, *, subgiants=True):
    """Stars per pc^3 of the evolved stars of ``comp`` at its reference point, in the M_G
    bins of edges ``mg_edges`` (module notes, item 6; rows beyond the edges go to the end
    bins): rho / mu (:func:`stars_per_imf_unit`) times the IMF times
    :func:`.evolved.row_weights`."""
    grid = load_evolved_isochrones()
    w = (stars_per_imf_unit(comp, isochrone_turnoff=True) * imf(grid.m_ini, comp.imf)
         * row_weights(comp, subgiants=subgiants))
    idx = np.clip(np.searchsorted(mg_edges, grid.m_g, side="right") - 1, 0, mg_edges.size - 2)
    return np.bincount(idx, weights=w, minlength=mg_edges.size - 1)


def _component_bins(components, *, local=None, faint_scale=1.0, subgiants=False, evolved_stars="wielen"):
    """Per component, the bins of its luminosity function in M_G: ``(lo, hi, n, part)``
    (bin edges, stars per pc^3, and which part of the local function each bin belongs to:
    :data:`PARTS`). The one construction behind :func:`build_luminosity_table` and
    :func:`build_part_table`, so their numbers cannot drift apart."""
    if evolved_stars not in EVOLVED_STARS:
        raise ValueError(f"evolved_stars={evolved_stars!r}; expected one of {EVOLVED_STARS}")
    if local is None:
        local = [c for c in components if c.law != "bulge" and c.lf_part != "giants"]
    local = [c for c in local if c.lf_part != "giants"]
    if evolved_stars == "parsec":
        return _isochrone_bins(components, local, faint_scale, subgiants)
    mv, phi = load_local_lf()
    giant_mv, giant_phi = mv[mv <= P.GIANT_MV_MAX], phi[mv <= P.GIANT_MV_MAX]
    # 1-mag bins: the sum of phi is the giants' density; scaled to Bovy (2017)
    giant_phi = giant_phi * (P.LOCAL_GIANT_DENSITY_PC3 / giant_phi.sum())
    dwarf_mv, dwarf_phi, _ = local_dwarf_lf(faint_scale)

    w_local_d = np.zeros(dwarf_mv.size)
    w_local_g = 0.0
    for c in local:
        wd, wg = component_weights(c, dwarf_mv)
        w_local_d += wd
        w_local_g += wg

    lo_v, hi_v = dwarf_mv - 0.5, dwarf_mv + 0.5
    lo_g_sol = lo_v + _g_minus_v(lo_v)
    hi_g_sol = hi_v + _g_minus_v(hi_v)
    glo = giant_mv - 0.5 + P.GIANT_G_MINUS_V
    ghi = giant_mv + 0.5 + P.GIANT_G_MINUS_V
    sub_mv, sub_phi = subgiant_lf() if subgiants else (np.zeros(0), np.zeros(0))
    slo = sub_mv - 0.5 + P.SUBGIANT_G_MINUS_V
    shi = sub_mv + 0.5 + P.SUBGIANT_G_MINUS_V
    part = np.concatenate([np.full(dwarf_mv.size, 0), np.full(giant_mv.size, 1), np.full(sub_mv.size, 2)])

    out = []
    for c in components:
        wd, wg = component_weights(c, dwarf_mv)
        n_dwarf = dwarf_phi * np.divide(wd, w_local_d, out=np.zeros_like(wd),
                                        where=w_local_d > 0)
        n_giant = giant_phi * (wg / w_local_g)
        n_sub = sub_phi * (wg / w_local_g)  # evolved stars, shared as the giants are
        # an age bin's giants (and subgiants) live in its giant-only companion (parameters.py)
        n_dwarf = n_dwarf * (c.lf_part != "giants")
        n_giant = n_giant * (c.lf_part != "dwarfs")
        n_sub = n_sub * (c.lf_part != "dwarfs")
        lo = np.concatenate([lo_g_sol - dwarf_shift(c), glo, slo])
        hi = np.concatenate([hi_g_sol - dwarf_shift(c), ghi, shi])
        n = np.concatenate([n_dwarf, n_giant, n_sub])
        out.append((lo, hi, n, part))
    return out


def _isochrone_bins(components, local, faint_scale, subgiants):
    """:func:`_component_bins` with the evolved stars from isochrones (module notes, item 6)."""
    dwarf_mv, dwarf_phi, _ = local_dwarf_lf(faint_scale, bright_end=True)
    w_local_d = sum(isochrone_dwarf_weights(c, dwarf_mv) for c in local)
    lo_v, hi_v = dwarf_mv - 0.5, dwarf_mv + 0.5
    lo_g_sol = lo_v + _g_minus_v(lo_v)
    hi_g_sol = hi_v + _g_minus_v(hi_v)
    edges = np.arange(MG_MIN, MG_MAX + 0.5 * MG_STEP, MG_STEP)
    part = np.concatenate([np.full(dwarf_mv.size, 0), np.full(edges.size - 1, 1)])
    out = []
    for c in components:
        wd = isochrone_dwarf_weights(c, dwarf_mv)
        n_dwarf = dwarf_phi * np.divide(wd, w_local_d, out=np.zeros_like(wd), where=w_local_d > 0)
        n_dwarf = n_dwarf * (c.lf_part != "giants")
        n_evolved = (evolved_lf(c, edges, subgiants=subgiants) if c.lf_part != "dwarfs"
                     else np.zeros(edges.size - 1))
        lo = np.concatenate([lo_g_sol - dwarf_shift(c), edges[:-1]])
        hi = np.concatenate([hi_g_sol - dwarf_shift(c), edges[1:]])
        out.append((lo, hi, np.concatenate([n_dwarf, n_evolved]), part))
    return out


def dwarf_shift(comp):
    """How much brighter (mag) the dwarfs of ``comp`` are than the solar-metallicity sequence
    of the same mass: the old metal-poor components' turn-off moved to
    :data:`.parameters.OLD_METAL_POOR_TURNOFF_MV` (module notes, item 4); 0 otherwise."""
    if not comp.metal_poor:
        return 0.0
    return float(_mv_of_mass(turnoff_mass(comp.age_gyr[1]))) - P.OLD_METAL_POOR_TURNOFF_MV


def _cdf_of_bins(mg, lo, hi, n):
    frac = np.clip((mg[None, :] - lo[:, None]) / (hi - lo)[:, None], 0.0, 1.0)
    return (n[:, None] * frac).sum(axis=0)


#: The parts of a component's luminosity function (:func:`build_part_table`): dwarfs (the
#: main sequence fainter than :data:`.parameters.GIANT_MV_MAX`), the bins treated as giants
#: (:data:`.parameters.GIANT_MV_MAX` and brighter) and the subgiants. With the evolved stars
#: from isochrones (``evolved_stars="parsec"``) the dwarfs are the whole main sequence, the
#: giants all evolved stars (subgiant branch included) and the subgiants part is empty.
PARTS = ("dwarfs", "giants", "subgiants")
#: Where the evolved stars come from: ``"parsec"`` the isochrones of each component's ages
#: and metallicities (:mod:`.evolved`; module notes, item 6), ``"wielen"`` the Wielen/Allen
#: bins with M_V <= :data:`.parameters.GIANT_MV_MAX` at Bovy's (2017) local giant density
#: plus the optional subgiants (items 1-5; galaxy models up to besancon-r03-5).
EVOLVED_STARS = ("parsec", "wielen")


def build_luminosity_table(components, *, local=None, faint_scale=1.0, subgiants=False,
                           evolved_stars="wielen"):
    """Luminosity functions in M_G of ``components`` (see module notes).

    Parameters
    ----------
    components : sequence of parameters.Component
        Components to tabulate.
    local : sequence of parameters.Component, optional
        Components present at the Sun that share the local luminosity function; by
        default all components except the bulge and the giant-only companions (which
        share the giants of their age bin). Passing the full model's list keeps a
        component's LF independent of which components are switched off.
    faint_scale : float
        Factor on the dwarfs fainter than :data:`.parameters.BOVY_PDMF_MV_MAX`.
    subgiants : bool
        Add the stars off the main sequence of :func:`subgiant_lf` (module notes, item 5);
        with ``evolved_stars="parsec"``, keep the isochrones' subgiant branch.
    evolved_stars : {"wielen", "parsec"}
        Where the evolved stars come from (:data:`EVOLVED_STARS`).

    Returns
    -------
    LuminosityTable
    """
    mg = np.arange(MG_MIN, MG_MAX + 0.5 * MG_STEP, MG_STEP)
    bins = _component_bins(components, local=local, faint_scale=faint_scale, subgiants=subgiants,
                           evolved_stars=evolved_stars)
    cdf = np.zeros((len(components), mg.size))
    for k, (lo, hi, n, _) in enumerate(bins):
        cdf[k] = _cdf_of_bins(mg, lo, hi, n)
    return LuminosityTable(names=tuple(c.name for c in components), mg=mg, cdf=cdf)


def build_part_table(components, *, local=None, faint_scale=1.0, subgiants=False, evolved_stars="wielen"):
    """The luminosity functions of :func:`build_luminosity_table` split into their
    :data:`PARTS`: what a star of given M_G is (a dwarf, one of the bins treated as giants,
    a subgiant), which its colour needs (:mod:`.colours`).

    Returns
    -------
    mg : ndarray, shape (K,)
        The absolute-magnitude grid of :func:`build_luminosity_table`.
    cdf : ndarray, shape (n_comp, len(PARTS), K)
        Stars per pc^3 brighter than ``mg``, per component and part (their sum over parts is
        the luminosity table's ``cdf`` to rounding).
    """
    mg = np.arange(MG_MIN, MG_MAX + 0.5 * MG_STEP, MG_STEP)
    bins = _component_bins(components, local=local, faint_scale=faint_scale, subgiants=subgiants,
                           evolved_stars=evolved_stars)
    cdf = np.zeros((len(components), len(PARTS), mg.size))
    for k, (lo, hi, n, part) in enumerate(bins):
        for p in range(len(PARTS)):
            sel = part == p
            cdf[k, p] = _cdf_of_bins(mg, lo[sel], hi[sel], n[sel])
    return mg, cdf
