"""The sweep's cells: directions x G bins, each with a stable identity.

A cell's identity is built from its content (direction and G range), not from its
position in a list, so the same cell draws the same stars in any sweep, in any order
and with any number of workers (SeedSequence(seed, spawn_key=cell.key)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from astropy import units as u
from astropy.coordinates import ICRS, Galactic, SkyCoord

from .conf import MagnitudesConf, SkyConf

__all__ = ["Direction", "Cell", "sky_directions", "magnitude_bins", "colour_bins", "enumerate_cells"]


@dataclass(frozen=True)
class Direction:
    """A pencil-beam centre, in both frames (degrees)."""

    index: int
    l_deg: float
    b_deg: float
    ra_deg: float
    dec_deg: float


#: Offset of the BP-RP edges in a cell's key, so the key stays non-negative (edges >= -5 mag,
#: :class:`~mcsweep.experiments.f90_sweep.conf.PriorModelConf`).
_COLOUR_KEY_OFFSET = 10.0


@dataclass(frozen=True)
class Cell:
    """One direction x one G bin, and optionally one BP-RP bin (the colour axis)."""

    direction: Direction
    g_min: float
    g_max: float
    #: BP-RP bin [mag]; None for a colour-blind cell (every star of the direction and G bin).
    bp_rp_min: float | None = None
    bp_rp_max: float | None = None

    @property
    def has_colour(self) -> bool:
        return self.bp_rp_min is not None

    @property
    def key(self) -> tuple[int, ...]:
        """Content-derived, non-negative integers (1e-4 deg, 0.01 mag resolution); a colour
        cell appends its BP-RP edges, so a colour-blind cell keeps the key (and the stars)
        it had before the colour axis existed."""
        d = self.direction
        key = (int(round(d.l_deg * 1e4)) % 3_600_000, int(round((d.b_deg + 90.0) * 1e4)),
               int(round(self.g_min * 100)), int(round(self.g_max * 100)))
        if self.has_colour:
            key += (int(round((self.bp_rp_min + _COLOUR_KEY_OFFSET) * 100)),
                    int(round((self.bp_rp_max + _COLOUR_KEY_OFFSET) * 100)))
        return key

    @property
    def cell_id(self) -> str:
        base = "cell_l{:09d}_b{:07d}_g{:04d}-{:04d}".format(*self.key[:4])
        return base + ("_c{:04d}-{:04d}".format(*self.key[4:]) if self.has_colour else "")


def sky_directions(sky: SkyConf) -> list[Direction]:
    """The directions of a sky config, ordered as HEALPix pixels or as listed."""
    if sky.kind == "healpix":
        from astropy_healpix import HEALPix

        frame = Galactic() if sky.frame == "galactic" else ICRS()
        hp = HEALPix(nside=sky.nside, order=sky.order, frame=frame)
        coords = hp.healpix_to_skycoord(np.arange(hp.npix))
    else:
        lon, lat = np.asarray(sky.directions, dtype=float).T
        frame = "galactic" if sky.frame == "galactic" else "icrs"
        coords = SkyCoord(lon * u.deg, lat * u.deg, frame=frame)
    gal = coords.galactic
    icrs = coords.icrs
    return [
        Direction(i, float(lv), float(bv), float(rv), float(dv))
        for i, (lv, bv, rv, dv) in enumerate(zip(gal.l.deg, gal.b.deg, icrs.ra.deg, icrs.dec.deg))
    ]


def magnitude_bins(mags: MagnitudesConf) -> list[tuple[float, float]]:
    e = [float(g) for g in mags.edges]
    return list(zip(e[:-1], e[1:]))


def colour_bins(colour_edges) -> list[tuple[float, float]]:
    e = [float(c) for c in colour_edges]
    return list(zip(e[:-1], e[1:]))


def enumerate_cells(sky: SkyConf, mags: MagnitudesConf, colour_edges=()) -> list[Cell]:
    """All cells, direction-major (cells of one direction share its transits); with
    ``colour_edges`` each direction x G cell is followed by its colour cells."""
    bins = magnitude_bins(mags)
    colours = [(None, None)] + colour_bins(colour_edges)
    return [Cell(d, g0, g1, c0, c1) for d in sky_directions(sky) for g0, g1 in bins for c0, c1 in colours]
