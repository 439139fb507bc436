"""The F90 sweep's config sections: the pencil-beam directions (``sky``), the G bins
(``magnitudes``), the prior grid (``prior_grid``), the cell procedure (``cell``), the Table 1
beam of Figs. 1-3 (``experiment.showcase``), the maps of the fitted prior (``prior_maps``) and the
prior model (``prior_model``: colour axis and prior mean)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, List

from ...astrometry.noise import G_MAX
from ...prior.maps import MAX_NSIDE
from ...prior.sky_grid import check_sky
from ..config_checks import require


@dataclass
class SkyConf:
    """Directions of the pencil beams (Sect. 3.4: 48 directions uniform on the sky)."""

    name: str = "healpix48"
    #: 'healpix' (pixel centres) or 'list' (explicit directions).
    kind: str = "healpix"
    nside: int = 2
    #: HEALPix pixel ordering: 'nested' or 'ring'.
    order: str = "nested"
    #: Frame of the HEALPix grid or of the listed directions: 'galactic' or 'icrs'.
    frame: str = "galactic"
    #: Explicit directions as [lon, lat] pairs in degrees (frame above), kind='list'.
    directions: List[Any] = field(default_factory=list)

    def __post_init__(self):
        # the one check of a sky (the prior checks a run's recorded sky with it too)
        grid = check_sky(dataclasses.asdict(self))
        if self.kind == "list":
            self.directions = grid["directions"]


@dataclass
class MagnitudesConf:
    """G-magnitude bin edges (paper Fig. 4: G = 6-20 in 1 mag bins)."""

    name: str = "g6_20"
    edges: List[float] = field(default_factory=lambda: [float(g) for g in range(6, 21)])

    def __post_init__(self):
        e = list(self.edges)
        require(len(e) >= 2, "magnitudes.edges", e, "at least two bin edges")
        require(all(0.0 <= g <= G_MAX for g in e), "magnitudes.edges", e,
                 f"G values within 0..{G_MAX:g} mag (the noise model's range)")
        require(all(b > a for a, b in zip(e[:-1], e[1:])), "magnitudes.edges", e,
                 "strictly increasing edges (non-empty bins)")


@dataclass
class PriorGridConf:
    """Logarithmic grid of parallax prior sigmas sigma_plx_p [mas] (Sect. 3.2-3.3)."""

    name: str = "default"
    min_mas: float = 0.01
    max_mas: float = 1000.0
    n: int = 41

    def __post_init__(self):
        require(self.min_mas > 0, "prior_grid.min_mas", self.min_mas, "a positive prior sigma in mas")
        require(self.max_mas > self.min_mas, "prior_grid.max_mas", self.max_mas,
                 f"a value larger than prior_grid.min_mas={self.min_mas}")
        require(self.n >= 2, "prior_grid.n", self.n, "at least 2 grid values")


@dataclass
class CellConf:
    """Pencil-beam cell procedure (Sect. 3.2-3.4); each value changes the answer."""

    #: Radius of the pencil beam (Table 1: 1 deg).
    beam_radius_deg: float = 1.0
    #: Cap on the stars drawn per cell (an unbiased subsample of the cone).
    max_stars: int = 20000
    #: Bright cells hold few stars: widen the beam around the same centre until this
    #: many stars are expected (all observed with the centre's transits).
    min_stars: int = 20000
    #: Largest radius the widening may reach.
    max_radius_deg: float = 20.0
    #: Interpolation of sigma_F90 between grid points: 'log' (in log sigma) or 'none'.
    interpolation: str = "log"
    #: Bootstrap resamples of the cell's stars for the sigma_F90 interval (0 = none).
    n_bootstrap: int = 200
    #: p_error_mas and median_semi_major_mas on every grid row of every cell (true), or
    #: only at sigma_F90 and in the showcase cell (false: NaN on the other grid rows).
    grid_statistics: bool = False

    def __post_init__(self):
        require(self.n_bootstrap >= 0, "cell.n_bootstrap", self.n_bootstrap,
                 "a number of resamples >= 0")
        require(0 < self.beam_radius_deg <= 90, "cell.beam_radius_deg", self.beam_radius_deg,
                 "a radius in (0, 90] deg")
        require(self.max_stars > 0, "cell.max_stars", self.max_stars, "a positive number of stars")
        require(self.min_stars > 0, "cell.min_stars", self.min_stars, "a positive number of stars")
        require(self.max_radius_deg >= self.beam_radius_deg, "cell.max_radius_deg",
                 self.max_radius_deg, f">= cell.beam_radius_deg={self.beam_radius_deg}")
        require(self.interpolation in ("log", "none"), "cell.interpolation", self.interpolation,
                 "'log' or 'none'")


@dataclass
class ShowcaseConf:
    """The single-direction experiment of the paper's Figs. 1-3 (Table 1 beam)."""

    enabled: bool = True
    ra_deg: float = 157.5
    dec_deg: float = 0.0
    g_min: float = 14.5
    g_max: float = 15.5
    #: Very tight and very loose priors of Fig. 2 (A and C), mas.
    tight_prior_mas: float = 0.01
    loose_prior_mas: float = 1000.0

    def __post_init__(self):
        require(0 <= self.ra_deg < 360, "experiment.showcase.ra_deg", self.ra_deg, "0..360 deg")
        require(-90 <= self.dec_deg <= 90, "experiment.showcase.dec_deg", self.dec_deg, "-90..90 deg")
        require(0 <= self.g_min < self.g_max <= G_MAX, "experiment.showcase.g_min/g_max",
                 (self.g_min, self.g_max), f"0 <= g_min < g_max <= {G_MAX:g}")
        require(self.tight_prior_mas > 0 and self.loose_prior_mas > self.tight_prior_mas,
                 "experiment.showcase priors", (self.tight_prior_mas, self.loose_prior_mas),
                 "0 < tight_prior_mas < loose_prior_mas")


@dataclass
class PriorMapsConf:
    """HEALPix maps of the fitted prior written with every sweep (``prior_maps.fits``)."""

    #: HEALPix resolution of the maps (galactic, RING): a power of two.
    nside: int = 16

    def __post_init__(self):
        require(isinstance(self.nside, int) and 1 <= self.nside <= MAX_NSIDE
                 and (self.nside & (self.nside - 1)) == 0,
                 "prior_maps.nside", self.nside, f"a power of two from 1 to {MAX_NSIDE}")


@dataclass
class PriorModelConf:
    """What the sweep's prior depends on and where it is centred.

    ``direction_g`` is the paper's (Sect. 3.4): a width per direction and G, centred on zero.
    ``colour_edges`` adds the star's BP-RP as an axis (the paper's suggested next step,
    Sect. 3.4: "blue stars have on average smaller parallaxes than red stars"): each
    direction x G cell is also run per colour bin. ``mean`` centres the prior on the model's
    mean parallax and proper motion of the cell instead of zero (Sect. 3.1; Sect. 5 keeps zero
    "since any other choice would necessarily involve additional assumptions"); the F90 criterion
    then sets the width around that mean.
    """

    name: str = "direction_g"
    #: BP-RP bin edges in mag (strictly increasing); empty: no colour axis.
    colour_edges: List[float] = field(default_factory=list)
    #: Centre the prior on the model's mean parallax and proper motion per cell.
    mean: bool = False

    def __post_init__(self):
        e = [float(v) for v in self.colour_edges]
        require(len(e) == 0 or (len(e) >= 2 and all(b > a for a, b in zip(e[:-1], e[1:]))
                                and all(-5.0 <= v <= 10.0 for v in e)),
                "prior_model.colour_edges", list(self.colour_edges),
                "[] (no colour axis) or at least two strictly increasing BP-RP edges within -5..10 mag")
        self.colour_edges = e
