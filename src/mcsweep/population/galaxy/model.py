"""The built-in galaxy model: exact expected counts and fast unbiased sampling.

For a cone, the model tabulates on a grid of distance moduli (step 0.05 mag) and on
sky cells (``mcsweep.population.sky``) the expected number of stars of each component
per grid cell, ``dn = rho_shape * dV * Omega``, and the extinction A_G. For a G range
the expected number in each (sky cell, component, distance cell) is ``dn`` times the
fraction of the component's luminosity function that falls in the range at that
distance and extinction; their sum is :meth:`~mcsweep.population.GalaxyModel.expected_count`.

Sampling draws the number of stars from a Poisson distribution (GUMS is one
realisation), then each star independently: a grid cell from the tabulated weights, a
distance with density ~ d^2 inside the cell, an absolute magnitude from the luminosity
function restricted to the G range at that distance (inverse CDF), a uniform position in
the sky cell, and a velocity from the component's ellipsoid. Capping the number drawn
(``max_stars``) therefore keeps the sample unbiased.

Randomness comes only from the ``rng`` passed in: it gives the count and one root seed;
stars are drawn in fixed blocks of ``DRAW_BLOCK_STARS``, block ``i`` from
``SeedSequence(root, spawn_key=(i,))``, so the result does not depend on how blocks are
grouped into chunks (``chunk_stars``) and memory stays flat. Each star's Gaia colour
(``bp_rp``, ``mcsweep.population.galaxy.colours``) needs one more uniform number, drawn from a stream of its own,
block ``i``'s from ``SeedSequence(root, spawn_key=(i, COLOUR_STREAM))``: the streams of the
other columns are untouched, so adding the colour changed none of them.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from functools import cache, lru_cache

import numpy as np
import pandas as pd

from ...errors import UserInputError
from .. import sky
from ..query import COLUMNS, POPULATION_CATEGORIES, ConeQuery
from . import parameters as P
from .density import component_shape, heliocentric_to_galactocentric
from .extinction import AG_OVER_AV, AV_PER_KPC, DUST_SCALE_HEIGHT_PC, DUST_SCALE_LENGTH_KPC, DustModel
from .colours import ColourTable, reddening_bp_rp
from .extinction_arenou import ArenouDust
from .kinematics import AstrometryTransform, draw_velocities, mean_lag_kms
from .luminosity import EVOLVED_STARS, build_luminosity_table

__all__ = ["GalaxyModel", "ConeDraw", "DEFAULT_PARAMS", "PARAMS_R03_5", "DRAW_BLOCK_STARS", "COLOUR_STREAM",
           "COLOUR_COLUMN", "gcns_faint_scale", "local_sources_per_pc3"]

#: Stars drawn per independently seeded block (block ``i`` from ``SeedSequence(root,
#: spawn_key=(i,))``, module notes). Why this size: a block's arrays (~80 bytes per star,
#: ~5 MB) stay small while the per-block seeding and table look-ups are amortised over
#: many stars. The value defines which stars share a random stream: changing it changes
#: every sample drawn with a given seed, so it is fixed.
DRAW_BLOCK_STARS = 65536
#: Second spawn-key element of the colour stream of block ``i``: ``SeedSequence(root,
#: spawn_key=(i, COLOUR_STREAM))`` (module notes). A stream apart from the block's own
#: ``(i,)``, so that the colour consumes none of the numbers the other columns are drawn from.
COLOUR_STREAM = 1
#: The column the galaxy model adds to :data:`~mcsweep.population.query.COLUMNS`: Gaia BP - RP
#: [mag], intrinsic colour plus reddening (``mcsweep.population.galaxy.colours``).
COLOUR_COLUMN = "bp_rp"
#: Distance-modulus grid: 2.5 pc to 79 kpc in steps of 0.05 mag (2.3 % in distance).
MU_MIN, MU_MAX, MU_STEP = -3.0, 19.5, 0.05
#: Largest number of stars drawn in one call (memory: ~80 bytes per star).
MAX_DRAW = 50_000_000
#: Largest sky cell, deg (whole-sky tables).
MAX_CELL_DEG = 5.0
_CACHE_SIZE = 64
#: Cumulative weights kept for this many recent (cone, G range) queries.
_WEIGHT_CACHE_SIZE = 8

#: User-adjustable parameters and their defaults (see ``conf/population/galaxy_model.yaml``).
DEFAULT_PARAMS = {
    "r0_kpc": P.R0_KPC,
    "z_sun_pc": P.Z_SUN_PC,
    "v_circ_kms": P.V_CIRC_KMS,
    "thin_disc_scale_height_factor": P.THIN_DISC_THICKNESS_FACTOR,
    "giant_thickness_factor": P.GIANT_THICKNESS_FACTOR,
    "young_disc_thickness_factor": P.YOUNG_DISC_THICKNESS_FACTOR,
    "extinction": True,
    "extinction_model": "arenou1992",
    "dust_av_per_kpc": AV_PER_KPC,
    "dust_scale_length_kpc": DUST_SCALE_LENGTH_KPC,
    "dust_scale_height_pc": DUST_SCALE_HEIGHT_PC,
    "ag_over_av": AG_OVER_AV,
    "components": list(POPULATION_CATEGORIES),
    "count": "poisson",
    "multiplicity_frequency": P.MULTIPLICITY_FREQUENCY,
    "subgiants": True,
    "evolved_stars": "parsec",
}

#: The parameters in which galaxy model besancon-r03-5 differs from :data:`DEFAULT_PARAMS`:
#: ``GalaxyModel(PARAMS_R03_5)`` is that model (its stars and colours as it drew them), for
#: comparisons and to rerun a study under it.
PARAMS_R03_5 = {
    "evolved_stars": "wielen",
    "giant_thickness_factor": 0.45,
    "young_disc_thickness_factor": 1.0,
    "thin_disc_scale_height_factor": 1.15,
}

#: ``extinction_model`` values: the smooth exponential disc (:mod:`.extinction`) alone, or
#: Arenou et al. (1992) near the Sun joined to the disc beyond (:mod:`.extinction_arenou`).
EXTINCTION_MODELS = ("disc", "arenou1992")

_POSITIVE = ("r0_kpc", "v_circ_kms", "thin_disc_scale_height_factor", "giant_thickness_factor",
             "young_disc_thickness_factor",
             "dust_scale_length_kpc", "dust_scale_height_pc", "ag_over_av")


def _check_params(p):
    unknown = sorted(set(p) - set(DEFAULT_PARAMS))
    if unknown:
        raise UserInputError(f"galaxy_model: unknown parameter(s) {unknown}; "
                             f"expected some of {sorted(DEFAULT_PARAMS)}")
    for key in _POSITIVE + ("z_sun_pc", "dust_av_per_kpc", "multiplicity_frequency"):
        try:
            v = float(p[key])
        except (TypeError, ValueError):
            raise UserInputError(f"galaxy_model: {key}={p[key]!r} is not accepted; "
                                 "expected a number") from None
        if not np.isfinite(v) or (key in _POSITIVE and v <= 0) or (
                key in ("dust_av_per_kpc", "multiplicity_frequency") and v < 0):
            raise UserInputError(f"galaxy_model: {key}={p[key]!r} is not accepted; expected a "
                                 f"{'positive' if key in _POSITIVE else 'finite'} number")
    for key in ("extinction", "subgiants"):
        if not isinstance(p[key], (bool, np.bool_)):
            raise UserInputError(f"galaxy_model: {key}={p[key]!r} is not accepted; expected true or false")
    if p["evolved_stars"] not in EVOLVED_STARS:
        raise UserInputError(f"galaxy_model: evolved_stars={p['evolved_stars']!r} is not "
                             f"accepted; expected one of {list(EVOLVED_STARS)}")
    if p["extinction_model"] not in EXTINCTION_MODELS:
        raise UserInputError(f"galaxy_model: extinction_model={p['extinction_model']!r} is not "
                             f"accepted; expected one of {list(EXTINCTION_MODELS)}")
    comps = p["components"]
    if isinstance(comps, str) or not comps or any(c not in POPULATION_CATEGORIES for c in comps):
        raise UserInputError(f"galaxy_model: components={comps!r} is not accepted; expected a "
                             f"non-empty list drawn from {list(POPULATION_CATEGORIES)}")
    if p["count"] not in ("poisson", "expected"):
        raise UserInputError(f"galaxy_model: count={p['count']!r} is not accepted; "
                             "expected 'poisson' or 'expected'")


def local_sources_per_pc3(lf, mg_max=P.GCNS_MG_LIMIT):
    """Sources per pc^3 with M_G < ``mg_max`` at the Sun, summed over the components of
    a :class:`.luminosity.LuminosityTable` (the bulge excluded)."""
    keep = [i for i, n in enumerate(lf.names) if n != "bulge"]
    return float(np.interp(mg_max, lf.mg, lf.cdf[keep].sum(axis=0)))


def gcns_faint_scale(subgiants=False, evolved_stars="wielen"):
    """Factor on the faint (Wielen/Allen) dwarfs that makes the model's sources with
    M_G < 15.5 within 100 pc equal the GCNS's (:data:`.parameters.GCNS_SOURCES_WITHIN_100PC`).

    The local luminosity function is linear in the factor, so two tabulations give it.
    The vertical fall-off of the discs within 100 pc (a few per cent) is neglected, as
    the GCNS count is compared with the density at the Sun.
    """
    return _gcns_faint_scale(bool(subgiants), str(evolved_stars))


@lru_cache(maxsize=None)
def _gcns_faint_scale(subgiants: bool, evolved_stars: str) -> float:
    comps = [c for c in P.COMPONENTS if c.law != "bulge"]
    d0, d1 = (local_sources_per_pc3(build_luminosity_table(comps, faint_scale=f, subgiants=subgiants,
                                                           evolved_stars=evolved_stars))
              for f in (0.0, 1.0))
    target = P.GCNS_SOURCES_WITHIN_100PC / (4.0 / 3.0 * np.pi * 100.0 ** 3)
    return (target - d0) / (d1 - d0)


@dataclass(frozen=True)
class _LineOfSight:
    grid: sky.CellGrid
    mu_edges: np.ndarray      # (J+1,)
    d3_edges: np.ndarray      # (J+1,) distance^3 in pc^3
    mu_mid: np.ndarray        # (J,)
    dn: np.ndarray            # (cells, comps, J) expected stars of all magnitudes
    a_nodes: np.ndarray       # (cells, J+1) A_G at mu_edges
    a_mid: np.ndarray         # (cells, J)


class GalaxyModel:
    """Besancon-like model of the Galaxy's stars (thin disc, thick disc, halo, bulge).

    Parameters
    ----------
    params : mapping, optional
        Model parameters (keys of ``DEFAULT_PARAMS``); keyword arguments override it.
    **kwargs
        Same keys as ``params``.

    Raises
    ------
    mcsweep.errors.UserInputError
        For unknown keys or values out of range.

    Notes
    -----
    Every number comes from a published source named in ``parameters``,
    ``luminosity``, ``extinction`` and ``kinematics`` (modules of ``mcsweep.population.galaxy``).

    The model counts *sources* (an unresolved multiple system counts once, as in Gaia
    and GUMS): its local luminosity function is calibrated to source counts (Bovy 2017
    for giants and main-sequence stars above 1 Msun, the GCNS of Smart et al. 2021 for the
    fainter dwarfs). ``multiplicity_frequency`` other than its default (0.27) rescales every
    magnitude by 1.27 / (1 + f), uniformly: ``multiplicity_frequency=0`` counts
    component stars (a simplification: companions are mostly faint M dwarfs).

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.population import GalaxyModel
    >>> model = GalaxyModel()
    >>> rng = np.random.default_rng(1)
    >>> stars = model.sample_cone(245.7, 46.5, 1.0, 15.0, 16.0, rng)
    >>> list(stars.columns[:8])
    ['ra', 'dec', 'l', 'b', 'parallax', 'pmra', 'pmdec', 'phot_g_mean_mag']
    """

    def __init__(self, params=None, **kwargs):
        p = dict(DEFAULT_PARAMS)
        p.update(dict(params or {}))
        p.update(kwargs)
        if "components" in p and not isinstance(p["components"], str):
            p["components"] = list(p["components"])
        _check_params(p)
        self.params = p
        self.chunk_stars = 4 * DRAW_BLOCK_STARS
        keep = set(p["components"])
        # the giants' discs at this model's thickness factor (velocities follow, parameters.py)
        young = float(p["young_disc_thickness_factor"])
        comps = (P.thin_disc(young) + P.thin_disc_giants(float(p["giant_thickness_factor"]), young)
                 + (P.THICK_DISC, P.HALO, P.BULGE))
        self.components = tuple(c for c in comps if c.label in keep)
        local = [c for c in P.COMPONENTS if c.law != "bulge" and c.lf_part != "giants"]
        parts = dict(subgiants=bool(p["subgiants"]), evolved_stars=p["evolved_stars"])
        faint = gcns_faint_scale(**parts)
        lf = build_luminosity_table(self.components, local=local, faint_scale=faint, **parts)
        # The calibrations (Bovy 2017, GCNS) count sources; counting component stars
        # instead (multiplicity_frequency=0) scales every magnitude alike.
        scale = (1.0 + P.MULTIPLICITY_FREQUENCY) / (1.0 + float(p["multiplicity_frequency"]))
        self.lf = type(lf)(lf.names, lf.mg, lf.cdf * scale)
        self._colour_args = dict(local=local, faint_scale=faint, **parts)
        self._colour_table = None
        self.dust = DustModel(
            av_per_kpc=p["dust_av_per_kpc"] if p["extinction"] else 0.0,
            scale_length_kpc=p["dust_scale_length_kpc"], scale_height_pc=p["dust_scale_height_pc"],
            ag_over_av=p["ag_over_av"], r0_kpc=p["r0_kpc"], z_sun_pc=p["z_sun_pc"])
        self.arenou = (ArenouDust(self.dust, ag_over_av=p["ag_over_av"])
                       if p["extinction"] and p["extinction_model"] == "arenou1992" else None)
        u, v, w = P.SOLAR_PECULIAR_KMS
        self.transform = AstrometryTransform(r0_kpc=p["r0_kpc"], z_sun_pc=p["z_sun_pc"],
                                             v_sun_kms=(u, p["v_circ_kms"] + v, w))
        eps = p["thin_disc_scale_height_factor"]
        self.lag_kms = np.array([mean_lag_kms(c, r0_kpc=p["r0_kpc"], z_sun_pc=p["z_sun_pc"],
                                              v_circ_kms=p["v_circ_kms"], eps_factor=eps)
                                 for c in self.components])
        self.sigma_uvw = np.array([c.sigma_uvw for c in self.components], float)
        self.label_codes = np.array([POPULATION_CATEGORIES.index(c.label) for c in self.components])
        self._cache = OrderedDict()
        self._wcache = OrderedDict()

    def __repr__(self):
        changed = {k: v for k, v in self.params.items() if v != DEFAULT_PARAMS[k]}
        return f"GalaxyModel({changed})"

    @property
    def colours(self):
        """The :class:`.colours.ColourTable` of this model's components (built on first use)."""
        if self._colour_table is None:
            self._colour_table = ColourTable.build(self.components, **self._colour_args)
        return self._colour_table

    # ----------------------------------------------------------------- tabulation
    def _line_of_sight(self, l_deg, b_deg, radius_deg):
        key = (round(l_deg, 9), round(b_deg, 9), min(radius_deg, sky.WHOLE_SKY_DEG))
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        p = self.params
        cell = min(max(radius_deg / 2.0, 0.05), MAX_CELL_DEG)
        grid = sky.cone_cells(l_deg, b_deg, radius_deg, cell)
        mu_edges = np.arange(MU_MIN, MU_MAX + 0.5 * MU_STEP, MU_STEP)
        d_edges_pc = 10.0 ** (0.2 * mu_edges + 1.0)
        mu_mid = 0.5 * (mu_edges[1:] + mu_edges[:-1])
        d_mid_kpc = 10.0 ** (0.2 * mu_mid - 2.0)
        geo = dict(r0_kpc=p["r0_kpc"], z_sun_pc=p["z_sun_pc"])
        x, y, z = heliocentric_to_galactocentric(grid.l_deg[:, None], grid.b_deg[:, None],
                                                 d_mid_kpc[None, :], **geo)
        shell_pc3 = (d_edges_pc[1:] ** 3 - d_edges_pc[:-1] ** 3) / 3.0
        dn = np.empty((grid.l_deg.size, len(self.components), mu_mid.size))
        for k, comp in enumerate(self.components):
            dn[:, k, :] = component_shape(comp, x, y, z, eps_factor=p["thin_disc_scale_height_factor"],
                                          **geo)
        dn *= shell_pc3[None, None, :] * grid.solid_angle_sr[:, None, None]
        xe, ye, ze = heliocentric_to_galactocentric(grid.l_deg[:, None], grid.b_deg[:, None],
                                                    d_edges_pc[None, :] * 1e-3, **geo)
        if self.arenou is None:
            a_nodes = self.dust.a_g(xe, ye, ze, d_edges_pc * 1e-3)
        else:
            a_nodes = self.arenou.a_g(grid.l_deg, grid.b_deg, xe, ye, ze, d_edges_pc * 1e-3)
        los = _LineOfSight(grid, mu_edges, d_edges_pc ** 3, mu_mid, dn, a_nodes,
                           0.5 * (a_nodes[:, 1:] + a_nodes[:, :-1]))
        self._cache[key] = los
        if len(self._cache) > _CACHE_SIZE:
            self._cache.popitem(last=False)
        return los

    def _weights(self, los, g_min, g_max):
        shift = los.mu_mid[None, :] + los.a_mid
        w = np.empty_like(los.dn)
        for k in range(len(self.components)):
            cdf = self.lf.cdf[k]
            w[:, k, :] = los.dn[:, k, :] * (np.interp(g_max - shift, self.lf.mg, cdf)
                                            - np.interp(g_min - shift, self.lf.mg, cdf))
        return w

    def _cumulative(self, q):
        """(line of sight, weight-array shape, cumulative weights) of a query, cached."""
        los = self._line_of_sight(q.l_deg, q.b_deg, q.radius_deg)
        key = (id(los), q.g_min, q.g_max)
        hit = self._wcache.get(key)
        if hit is not None and hit[0] is los:
            self._wcache.move_to_end(key)
            return hit
        w = self._weights(los, q.g_min, q.g_max)
        entry = (los, w.shape, np.cumsum(w.ravel()))
        self._wcache[key] = entry
        if len(self._wcache) > _WEIGHT_CACHE_SIZE:
            self._wcache.popitem(last=False)
        return entry

    # ----------------------------------------------------------------- public API
    def expected_count(self, l_deg, b_deg, radius_deg, g_min, g_max):
        """Expected number of stars in a cone and G range.

        Parameters
        ----------
        l_deg, b_deg : float
            Cone centre, Galactic coordinates, deg.
        radius_deg : float
            Cone radius, deg (>= 180: whole sky).
        g_min, g_max : float
            Apparent G range, mag (g_min <= G < g_max).

        Returns
        -------
        float
            Expected number of stars.

        Examples
        --------
        >>> from mcsweep.population import GalaxyModel
        >>> # the paper's Table 1 beam (GUMS: 458)
        >>> round(GalaxyModel().expected_count(245.7, 46.5, 1.0, 14.5, 15.5))
        455
        """
        q = ConeQuery.make(l_deg, b_deg, radius_deg, g_min, g_max)
        return float(self._cumulative(q)[2][-1])

    def expected_count_by_population(self, l_deg, b_deg, radius_deg, g_min, g_max):
        """Expected number of stars in a cone and G range, per population.

        Parameters
        ----------
        l_deg, b_deg : float
            Cone centre, Galactic coordinates, deg.
        radius_deg : float
            Cone radius, deg (>= 180: whole sky).
        g_min, g_max : float
            Apparent G range, mag (g_min <= G < g_max).

        Returns
        -------
        dict
            Population label (the model's components, e.g. ``thin_disc``) -> expected
            number of stars.

        Examples
        --------
        >>> from mcsweep.population import GalaxyModel
        >>> model = GalaxyModel()
        >>> beam = (245.7, 46.5, 1.0)  # l, b, radius [deg]
        >>> counts = model.expected_count_by_population(*beam, 14.5, 15.5)
        >>> sorted(counts)
        ['bulge', 'halo', 'thick_disc', 'thin_disc']
        """
        q = ConeQuery.make(l_deg, b_deg, radius_deg, g_min, g_max)
        w = self._weights(self._line_of_sight(q.l_deg, q.b_deg, q.radius_deg), q.g_min, q.g_max)
        per = w.sum(axis=(0, 2))
        out = {}
        for k, comp in enumerate(self.components):
            out[comp.label] = out.get(comp.label, 0.0) + float(per[k])
        return out

    #: More stars of a cone can be drawn from the model's density than one realisation
    #: holds (``min_draw`` of :meth:`sample_cone`); catalogues cannot do this.
    draws_from_density = True
    #: :meth:`sample_cone` can skip the colours (``colours=False``).
    colours_optional = True

    def sample_cone(self, l_deg, b_deg, radius_deg, g_min, g_max, rng, max_stars=None, *, min_draw=None,
                    colours=True):
        """Draw the stars of a cone and G range.

        Parameters
        ----------
        l_deg, b_deg : float
            Cone centre, Galactic coordinates, deg.
        radius_deg : float
            Cone radius, deg (>= 180: whole sky).
        g_min, g_max : float
            Apparent G range, mag.
        rng : numpy.random.Generator
            Source of randomness.
        max_stars : int, optional
            Cap on the number of stars returned; the kept stars are an unbiased sample.
        min_draw : int, optional, keyword-only
            Draw at least this many stars (still capped by ``max_stars``): when one
            realisation of the cone holds fewer, the extra stars are further independent
            draws from the same density, so the cone keeps its size (the pencil-beam rule
            of ``mcsweep.experiments.f90_sweep.pencil_beam``). ``n_in_cone`` stays the count of
            one realisation.
        colours : bool, keyword-only
            False: skip the colour stage (``bp_rp`` is NaN), for a caller that does not use the
            colours (the sweep's colour-blind cells; 2 ms of a 20 000-star draw). The colours
            draw from a stream of their own (module notes), so every other column is the same
            bit for bit.

        Returns
        -------
        pandas.DataFrame
            Columns ``ra, dec, l, b`` [deg], ``parallax`` [mas], ``pmra, pmdec`` [mas/yr],
            ``phot_g_mean_mag`` [mag], ``distance_pc`` [pc], ``population`` (categorical),
            ``bp_rp`` [mag] (Gaia BP - RP with reddening, ``mcsweep.population.galaxy.colours``;
            NaN with ``colours=False``).
            ``attrs["n_in_cone"]`` is the number of stars in the cone (before the cap) and
            ``attrs["expected_count"]`` its expectation.

        Examples
        --------
        >>> import numpy as np
        >>> from mcsweep.population import GalaxyModel
        >>> rng = np.random.default_rng(7)
        >>> stars = GalaxyModel().sample_cone(0.0, 0.0, 0.5, 12.0, 13.0, rng,
        ...                                   max_stars=100)
        >>> len(stars), stars.attrs['n_in_cone'] > 100
        (100, True)
        """
        q, (los, shape, cum), n_in, n, root = self._plan(l_deg, b_deg, radius_deg, g_min, g_max, rng, max_stars,
                                                         min_draw)
        df = self._draw(los, shape, cum, q.g_min, q.g_max, n, root, colours=bool(colours))
        df.attrs["n_in_cone"] = n_in
        df.attrs["expected_count"] = float(cum[-1])
        return df

    def draw_cone(self, l_deg, b_deg, radius_deg, g_min, g_max, rng, max_stars=None, *, min_draw=None):
        """The stars of :meth:`sample_cone`, drawn as far as their colours need.

        Parameters
        ----------
        l_deg, b_deg : float
            Cone centre, Galactic coordinates, deg.
        radius_deg : float
            Cone radius, deg (>= 180: whole sky).
        g_min, g_max : float
            Apparent G range, mag.
        rng : numpy.random.Generator
            Source of randomness: the same state gives the stars :meth:`sample_cone` gives.
        max_stars : int, optional
            Cap on the number of stars drawn (as for :meth:`sample_cone`).
        min_draw : int, optional, keyword-only
            Draw at least this many stars (as for :meth:`sample_cone`).

        Returns
        -------
        ConeDraw
            ``bp_rp`` of every star; ``stars(index)`` the table of :meth:`sample_cone` for the
            given rows only, the positions and motions of the other stars never computed (a
            caller keeping the stars of one colour skips the rest of the draw's arithmetic for
            the others). Each star's values are those of :meth:`sample_cone`, bit for bit
            (tested on this platform's numpy and BLAS: tests/population/test_draw_kernel.py).
            It holds the stars' random numbers and colour-stage values, about 130 bytes per
            star, and draws them in one piece (``sample_cone`` in chunks): for a whole large
            cone, ``sample_cone``.

        Examples
        --------
        >>> import numpy as np
        >>> from mcsweep.population import GalaxyModel
        >>> model = GalaxyModel()
        >>> cone = (0.0, 0.0, 0.5, 12.0, 13.0)  # l, b, radius [deg], G range
        >>> drawn = model.draw_cone(*cone, np.random.default_rng(7),
        ...                         max_stars=100)
        >>> red = np.flatnonzero(drawn.bp_rp > 1.5)
        >>> table = model.sample_cone(*cone, np.random.default_rng(7),
        ...                           max_stars=100)
        >>> drawn.stars(red).equals(table.iloc[red].reset_index(drop=True))
        True
        """
        q, (los, shape, cum), n_in, n, root = self._plan(l_deg, b_deg, radius_deg, g_min, g_max, rng, max_stars,
                                                         min_draw)
        uni, nor, u_colour = self._random_numbers(n, 0, n, root)
        first = self._first_stage(los, shape, cum, q.g_min, q.g_max, uni, u_colour)

        def gather(idx):
            return {k: v[idx] for k, v in first.items()}, uni[3][idx], uni[4][idx], nor[:, idx]

        def finish(first_rows, u_cos, u_psi, normals):
            return self._second_stage(los, q.g_min, q.g_max, first_rows, u_cos, u_psi, normals)

        return ConeDraw(first["bp_rp"], n_in, float(cum[-1]), gather, finish, query=(self, los, q.g_min, q.g_max))

    def _plan(self, l_deg, b_deg, radius_deg, g_min, g_max, rng, max_stars, min_draw):
        """The query, its tabulation, the count of one realisation, the number to draw and the
        root seed (the only numbers taken from ``rng``)."""
        if not isinstance(rng, np.random.Generator):
            raise UserInputError(f"rng={rng!r} is not accepted; expected a numpy.random.Generator")
        q = ConeQuery.make(l_deg, b_deg, radius_deg, g_min, g_max, max_stars)
        tab = self._cumulative(q)
        total = float(tab[2][-1])
        n_in = int(rng.poisson(total)) if self.params["count"] == "poisson" else int(round(total))
        n = n_in if min_draw is None or total <= 0 else max(n_in, int(min_draw))
        n = n if q.max_stars is None else min(n, q.max_stars)
        if n > MAX_DRAW:
            raise UserInputError(f"the query holds {n_in} stars, more than {MAX_DRAW} can be drawn "
                                 "at once; expected max_stars (an unbiased subsample) or a "
                                 "smaller cone / G range")
        return q, tab, n_in, n, int(rng.integers(0, 2 ** 63 - 1))

    def sample_sky(self, g_min, g_max, rng, max_stars=None):
        """Draw stars over the whole sky.

        Parameters
        ----------
        g_min, g_max : float
            Apparent G range, mag.
        rng : numpy.random.Generator
            Source of randomness.
        max_stars : int, optional
            Cap on the number of stars returned; the kept stars are an unbiased sample.

        Returns
        -------
        pandas.DataFrame
            The columns of :meth:`sample_cone`.

        Examples
        --------
        >>> import numpy as np
        >>> from mcsweep.population import GalaxyModel
        >>> rng = np.random.default_rng(7)
        >>> stars = GalaxyModel().sample_sky(4.0, 5.0, rng)
        >>> len(stars) > 1000  # the whole sky's stars of G = 4-5
        True
        """
        return self.sample_cone(0.0, 90.0, sky.WHOLE_SKY_DEG, g_min, g_max, rng, max_stars)

    # ----------------------------------------------------------------- drawing
    def _draw(self, los, shape, cum, g_min, g_max, n, root, *, colours=True):
        cols = {c: np.empty(n) for c in COLUMNS[:-1] + (COLOUR_COLUMN,)}
        codes = np.empty(n, dtype=np.int64)
        n_blocks = -(-n // DRAW_BLOCK_STARS)
        per_chunk = max(1, self.chunk_stars // DRAW_BLOCK_STARS)
        for first in range(0, n_blocks, per_chunk):
            start = first * DRAW_BLOCK_STARS
            stop = min(n, (first + per_chunk) * DRAW_BLOCK_STARS)
            uni, nor, u_colour = self._random_numbers(n, start, stop, root, colours=colours)
            part, part_codes = self._stars(los, shape, cum, g_min, g_max, uni, nor, u_colour)
            for c, v in part.items():
                cols[c][start:stop] = v
            codes[start:stop] = part_codes
        return self._frame(cols, codes)

    @staticmethod
    def _random_numbers(n, start, stop, root, *, colours=True):
        """The uniform (5, m), normal (3, m) and colour (m,) numbers of stars ``start:stop`` of
        ``n`` (``start`` on a block boundary), block by block from their own streams; without
        ``colours`` the colour numbers are None (their stream is not drawn)."""
        uni = np.empty((5, stop - start))
        nor = np.empty((3, stop - start))
        u_colour = np.empty(stop - start) if colours else None
        for i in range(start // DRAW_BLOCK_STARS, -(-stop // DRAW_BLOCK_STARS)):
            a = i * DRAW_BLOCK_STARS - start
            m = min(DRAW_BLOCK_STARS, n - i * DRAW_BLOCK_STARS)
            gen = np.random.default_rng(np.random.SeedSequence(root, spawn_key=(i,)))
            uni[:, a:a + m] = gen.random((5, m))
            nor[:, a:a + m] = gen.standard_normal((3, m))
            if colours:
                u_colour[a:a + m] = np.random.default_rng(
                    np.random.SeedSequence(root, spawn_key=(i, COLOUR_STREAM))).random(m)
        return uni, nor, u_colour

    def _stars(self, los, shape, cum, g_min, g_max, uni, normals, u_colour):
        first = self._first_stage(los, shape, cum, g_min, g_max, uni, u_colour)
        return self._second_stage(los, g_min, g_max, first, uni[3], uni[4], normals)

    def _first_stage(self, los, shape, cum, g_min, g_max, uni, u_colour) -> dict:
        """Each star's grid cell, component, distance, extinction, M_G and colour: what its
        BP-RP needs (uniform numbers 0-2 and the colour stream's; ``u_colour`` None: no colour,
        BP-RP NaN)."""
        # searchsorted is much faster on sorted queries (cache); the result is unchanged
        target = uni[0] * cum[-1]
        order = np.argsort(target)
        idx = np.empty(target.size, dtype=np.intp)
        idx[order] = np.searchsorted(cum, target[order], side="right")
        np.minimum(idx, cum.size - 1, out=idx)
        cell, k, j = np.unravel_index(idx, shape)
        d3 = los.d3_edges[j] + uni[1] * (los.d3_edges[j + 1] - los.d3_edges[j])
        d_pc = np.cbrt(d3)
        mu = 5.0 * np.log10(d_pc) - 5.0
        frac = (mu - los.mu_edges[j]) / MU_STEP
        a_g = los.a_nodes[cell, j] + frac * (los.a_nodes[cell, j + 1] - los.a_nodes[cell, j])
        # M_G from each star's component's luminosity function, restricted to the G range at
        # its distance modulus and extinction and inverted at a uniform number (compiled,
        # the numpy arithmetic star by star: draw_kernel).
        from .draw_kernel import absolute_magnitudes  # numba where stars are drawn

        m_g = np.empty(mu.size)
        absolute_magnitudes(k, mu, a_g, uni[2], float(g_min), float(g_max), self.lf.mg, self.lf.cdf, m_g)
        if u_colour is None:
            bp_rp = np.full(m_g.size, np.nan)
        else:
            bp_rp0, part = self.colours.intrinsic(k, m_g, u_colour)
            upper_hrd = (part == 1) if self.colours.upper_hrd_law else None
            bp_rp = bp_rp0 + reddening_bp_rp(bp_rp0, a_g / float(self.params["ag_over_av"]), upper_hrd)
        return dict(cell=cell, k=k, d_pc=d_pc, mu=mu, a_g=a_g, m_g=m_g, bp_rp=bp_rp)

    def _second_stage(self, los, g_min, g_max, first: dict, u_cos, u_psi, normals):
        """The table's columns from :meth:`_first_stage`'s values, the position's uniform
        numbers (3 and 4) and the velocity's normals, star by star; returns (columns, codes)."""
        cell, k, d_pc = first["cell"], first["k"], first["d_pc"]
        g = np.clip(first["m_g"] + first["mu"] + first["a_g"], g_min, np.nextafter(g_max, -np.inf))
        l, b, n_gal = los.grid.sample(cell, u_cos, u_psi, with_vectors=True)
        d_kpc = d_pc * 1e-3
        x = d_kpc * n_gal[0] - self.params["r0_kpc"]      # same geometry as density.py
        y = d_kpc * n_gal[1]
        v = draw_velocities(x, y, self.lag_kms[k], self.sigma_uvw[k], normals,
                            v_circ_kms=self.params["v_circ_kms"])
        ra, dec, pmra, pmdec = self.transform.astrometry(l, b, d_kpc, v, gal_unit=n_gal)
        cols = {"ra": ra, "dec": dec, "l": l, "b": b, "parallax": 1000.0 / d_pc,
                "pmra": pmra, "pmdec": pmdec, "phot_g_mean_mag": g, "distance_pc": d_pc,
                COLOUR_COLUMN: first["bp_rp"]}
        return cols, self.label_codes[k]

    @staticmethod
    def _frame(cols, codes):
        data = dict(cols)
        data["population"] = pd.Categorical.from_codes(codes, dtype=_population_dtype())
        return pd.DataFrame(data, columns=[*COLUMNS, COLOUR_COLUMN], copy=False)


@cache
def _population_dtype() -> pd.CategoricalDtype:
    # One dtype for every table: pandas builds and checks the categories' index for each new
    # one (50 us, and a colour cell makes a table per batch it takes stars from).
    return pd.CategoricalDtype(POPULATION_CATEGORIES)


def _same_query(a: tuple, b: tuple) -> bool:
    # the same model and line of sight (objects), the same G range (values)
    return a[0] is b[0] and a[1] is b[1] and a[2:] == b[2:]


#: Fewest rows :meth:`ConeDraw.stars` computes at once.
_MIN_ROWS = 16


class ConeDraw:
    """The stars of one cone draw (:meth:`~mcsweep.population.GalaxyModel.draw_cone`): their
    colours, and their table made on request for the rows asked for.

    Parameters
    ----------
    bp_rp : ndarray
        Each star's Gaia BP - RP, mag (the ``bp_rp`` column of
        :meth:`~mcsweep.population.GalaxyModel.sample_cone`).
    n_in_cone : int
        The number of stars in one realisation of the cone (``attrs["n_in_cone"]``).
    expected_count : float
        Its expectation (``attrs["expected_count"]``).
    gather : callable
        ``gather(index)``: what the rest of the draw needs of the stars at the integer
        positions ``index``, a tuple of arrays over those stars (each star's values in its own
        element).
    finish : callable
        ``finish(*gathered)``: the columns (dict of arrays) and population codes of the stars
        gathered, computed element by element.
    query : tuple, optional
        What ``finish`` depends on besides the stars (model, line of sight, G range): draws
        with the same model and line of sight (objects) and G range can be finished together
        (:meth:`stars_of`).

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.population import GalaxyModel
    >>> rng = np.random.default_rng(7)
    >>> drawn = GalaxyModel().draw_cone(0.0, 0.0, 0.5, 12.0, 13.0, rng,
    ...                                 max_stars=100)
    >>> len(drawn), drawn.n_in_cone > 100
    (100, True)
    """

    def __init__(self, bp_rp, n_in_cone, expected_count, gather, finish, *, query=None):
        self.bp_rp = bp_rp
        self.n_in_cone = n_in_cone
        self.expected_count = expected_count
        self._gather = gather
        self._finish = finish
        self._query = query

    def __len__(self) -> int:
        return self.bp_rp.size

    def stars(self, index=None) -> pd.DataFrame:
        """The table of :meth:`~mcsweep.population.GalaxyModel.sample_cone` (same columns, attrs
        and values), of the rows ``index`` (integer positions, in the order given) or of all
        stars.

        Parameters
        ----------
        index : array_like of int or bool, optional
            Rows to make (integer positions, or a mask over all stars); all if omitted.

        Returns
        -------
        pandas.DataFrame
            One row per star of ``index``, numbered from 0.

        Examples
        --------
        >>> import numpy as np
        >>> from mcsweep.population import GalaxyModel
        >>> rng = np.random.default_rng(7)
        >>> drawn = GalaxyModel().draw_cone(0.0, 0.0, 0.5, 12.0, 13.0, rng,
        ...                                 max_stars=100)
        >>> len(drawn.stars([0, 5, 9])), len(drawn.stars())
        (3, 100)
        """
        idx = self._positions(index)
        n = idx.size
        # A handful of rows is computed as at least _MIN_ROWS (repeated): numpy and BLAS take
        # other routes for arrays of one element (matrix-vector products, scalar loops), whose
        # last bits differ from the whole draw's.
        cols, codes = self._finish(*self._gather(np.resize(idx, _MIN_ROWS) if 0 < n < _MIN_ROWS else idx))
        df = GalaxyModel._frame({c: v[:n] for c, v in cols.items()}, codes[:n])
        df.attrs.update(self._attrs())
        return df

    @staticmethod
    def stars_of(parts) -> pd.DataFrame:
        """The rows of several draws as one table: ``pd.concat([draw.stars(index) for draw, index
        in parts], ignore_index=True)``, the same values and attrs, bit for bit.

        Draws of one query (:meth:`~mcsweep.population.GalaxyModel.draw_cone` of one model, cone
        and G range: a colour cell's batches) are finished in one pass over all their rows: one
        table instead of one per draw (0.5 ms each) and their concatenation.

        Parameters
        ----------
        parts : sequence of (ConeDraw, index)
            At least one; ``index`` as for :meth:`stars`.

        Returns
        -------
        pandas.DataFrame
            The rows of every part in order, numbered from 0.

        Examples
        --------
        >>> import numpy as np
        >>> import pandas as pd
        >>> from mcsweep.population import GalaxyModel
        >>> from mcsweep.population.galaxy.model import ConeDraw
        >>> model = GalaxyModel()
        >>> cone = (0.0, 0.0, 0.5, 12.0, 13.0)  # l, b, radius [deg], G range
        >>> a, b = (model.draw_cone(*cone, np.random.default_rng(i), max_stars=100)
        ...         for i in (1, 2))
        >>> parts = [(a, a.bp_rp > 1.5), (b, b.bp_rp > 1.5)]  # one colour bin
        >>> ConeDraw.stars_of(parts).equals(
        ...     pd.concat([d.stars(i) for d, i in parts], ignore_index=True))
        True
        """
        parts = [(draw, draw._positions(index)) for draw, index in parts]
        first = parts[0][0]._query
        together = first is not None and all(d._query is not None and _same_query(d._query, first) for d, _ in parts)
        n = sum(idx.size for _, idx in parts)
        if not together or n < _MIN_ROWS:
            return pd.concat([d.stars(idx) for d, idx in parts], ignore_index=True)
        gathered = [d._gather(idx) for d, idx in parts]
        rows, u_cos, u_psi, normals = gathered[0]
        rows = {k: np.concatenate([g[0][k] for g in gathered]) for k in rows}
        u_cos = np.concatenate([g[1] for g in gathered])
        u_psi = np.concatenate([g[2] for g in gathered])
        normals = np.concatenate([g[3] for g in gathered], axis=1)
        cols, codes = parts[0][0]._finish(rows, u_cos, u_psi, normals)
        df = GalaxyModel._frame(cols, codes)
        # pd.concat keeps the attrs only where all its tables have the same
        attrs = [d._attrs() for d, _ in parts]
        if all(a == attrs[0] for a in attrs):
            df.attrs.update(attrs[0])
        return df

    def _attrs(self) -> dict:
        return {"n_in_cone": self.n_in_cone, "expected_count": self.expected_count}

    def _positions(self, index) -> np.ndarray:
        """``index`` of :meth:`stars` as integer positions (all stars if None)."""
        if index is None:
            return np.arange(len(self))
        idx = np.asarray(index)
        if idx.dtype == bool:
            if idx.shape != (len(self),):
                raise UserInputError(f"a mask of shape {idx.shape} was given for {len(self)} stars; "
                                     "expected one flag per star")
            idx = np.flatnonzero(idx)
        return idx.astype(np.intp, casting="safe" if idx.size else "unsafe")
