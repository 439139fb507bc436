"""Cones on the sky: partition into cells, uniform sampling, membership tests.

A cone (spherical cap) of radius ``r`` around a Galactic direction is split into rings
of equal width in angular distance, and each ring into equal azimuth sectors, so that
cells are roughly square with side ~ ``cell_deg``. Every cell has an exact solid angle
and can be sampled uniformly (cos(theta) uniform within the ring, azimuth uniform within
the sector), which lets a model evaluate the star density at cell centres and still draw
exactly uniform positions within each cell. A radius >= 180 deg is the whole sky.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scanning.frames import tangent_triad

__all__ = ["WHOLE_SKY_DEG", "CellGrid", "cone_cells", "cone_axes", "in_cone"]

#: Radius at and beyond which a cone is the whole sky, deg.
WHOLE_SKY_DEG = 180.0


def _unit(l_deg, b_deg):
    # Components first, shape (3, ...), as the cone code indexes them.
    return np.moveaxis(tangent_triad(l_deg, b_deg)[2], -1, 0)


def cone_axes(l_deg, b_deg):
    """Rotation matrix whose columns are (east, north, centre) at a Galactic direction."""
    return np.stack(tangent_triad(float(l_deg), float(b_deg)), axis=1)


@dataclass(frozen=True)
class CellGrid:
    """Cells of a cone.

    Attributes
    ----------
    l_deg, b_deg : ndarray, shape (n,)
        Galactic coordinates of the cell centres, deg.
    solid_angle_sr : ndarray, shape (n,)
        Exact solid angle of each cell, sr (they add up to the cone's).
    cos_lo, cos_hi : ndarray, shape (n,)
        Range of cos(theta) (theta = angular distance from the cone centre).
    psi_lo, psi_width : ndarray, shape (n,)
        Azimuth range (rad) around the centre, measured from east through north.
    axes : ndarray, shape (3, 3)
        Columns east, north, centre of the cone centre (Galactic Cartesian).
    """

    l_deg: np.ndarray
    b_deg: np.ndarray
    solid_angle_sr: np.ndarray
    cos_lo: np.ndarray
    cos_hi: np.ndarray
    psi_lo: np.ndarray
    psi_width: np.ndarray
    axes: np.ndarray

    def _to_lb(self, cos_t, psi):
        return self._vectors(cos_t, psi)[:2]

    def _vectors(self, cos_t, psi):
        sin_t = np.sqrt(np.clip(1.0 - cos_t * cos_t, 0.0, None))
        v = self.axes @ np.stack([sin_t * np.cos(psi), sin_t * np.sin(psi), cos_t])
        l = np.degrees(np.arctan2(v[1], v[0])) % 360.0
        b = np.degrees(np.arcsin(np.clip(v[2], -1.0, 1.0)))
        return l, b, v

    def sample(self, cell, u_cos, u_psi, *, with_vectors=False):
        """Uniform positions inside the given cells.

        Parameters
        ----------
        cell : ndarray of int, shape (n,)
            Cell index of each point.
        u_cos, u_psi : ndarray, shape (n,)
            Uniform deviates in [0, 1).
        with_vectors : bool
            Also return the Galactic Cartesian unit vectors, shape (3, n).

        Returns
        -------
        l_deg, b_deg : ndarray, shape (n,)
            (and the unit vectors if ``with_vectors``)
        """
        cos_t = self.cos_lo[cell] + u_cos * (self.cos_hi[cell] - self.cos_lo[cell])
        psi = self.psi_lo[cell] + u_psi * self.psi_width[cell]
        out = self._vectors(cos_t, psi)
        return out if with_vectors else out[:2]


def cone_cells(l_deg, b_deg, radius_deg, cell_deg):
    """Split a cone into cells of side about ``cell_deg``.

    Parameters
    ----------
    l_deg, b_deg : float
        Cone centre, Galactic, deg (ignored for the whole sky, which is centred on the
        north Galactic pole).
    radius_deg : float
        Cone radius, deg; >= 180 means the whole sky.
    cell_deg : float
        Target cell size, deg.

    Returns
    -------
    CellGrid
    """
    if radius_deg >= WHOLE_SKY_DEG:
        l_deg, b_deg, radius_deg = 0.0, 90.0, WHOLE_SKY_DEG
    axes = cone_axes(l_deg, b_deg)
    n_ring = max(1, int(np.ceil(radius_deg / cell_deg)))
    edges = np.radians(np.linspace(0.0, radius_deg, n_ring + 1))
    cl, ch, pl, pw, mid_t, mid_p = [], [], [], [], [], []
    for t0, t1 in zip(edges[:-1], edges[1:]):
        tm = 0.5 * (t0 + t1)
        n_az = max(3 if t0 == 0.0 else 4,
                   int(round(2.0 * np.pi * np.sin(tm) / np.radians(cell_deg))))
        width = 2.0 * np.pi / n_az
        psi0 = np.arange(n_az) * width
        cl.append(np.full(n_az, np.cos(t1)))
        ch.append(np.full(n_az, np.cos(t0)))
        pl.append(psi0)
        pw.append(np.full(n_az, width))
        # centre of the cell: mean cos(theta) (area centroid in theta) and mid azimuth
        mid_t.append(np.full(n_az, np.arccos(0.5 * (np.cos(t0) + np.cos(t1)))))
        mid_p.append(psi0 + 0.5 * width)
    cos_lo, cos_hi = np.concatenate(cl), np.concatenate(ch)
    psi_lo, psi_w = np.concatenate(pl), np.concatenate(pw)
    grid = CellGrid(np.empty(0), np.empty(0), (cos_hi - cos_lo) * psi_w, cos_lo, cos_hi,
                    psi_lo, psi_w, axes)
    lc, bc = grid._to_lb(np.cos(np.concatenate(mid_t)), np.concatenate(mid_p))
    return CellGrid(lc, bc, grid.solid_angle_sr, cos_lo, cos_hi, psi_lo, psi_w, axes)


def in_cone(l_deg, b_deg, l0_deg, b0_deg, radius_deg):
    """Boolean mask of directions within ``radius_deg`` of (l0, b0) (all True if >= 180)."""
    if radius_deg >= WHOLE_SKY_DEG:
        return np.ones(np.shape(l_deg), dtype=bool)
    c = _unit(l0_deg, b0_deg)
    v = _unit(np.asarray(l_deg, float), np.asarray(b_deg, float))
    return np.tensordot(c, v, axes=(0, 0)) >= np.cos(np.radians(radius_deg))
