"""ICRS (ra, dec) to galactic (l, b) for large arrays, with astropy's own rotation.

Below every stage: the population draws and matches stars by galactic direction and the
prior is a function of it (Eq. 14).

astropy's ICRS -> Galactic transformation is a fixed rotation (through FK5 J2000 and
the frame bias; no epoch dependence), so the matrix is taken once from astropy by
transforming the three ICRS basis vectors and then applied with numpy. This keeps
catalogue annotation at millions of rows per second while agreeing with
``SkyCoord(...).galactic`` to rounding (tests/test_galactic.py).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["icrs_to_galactic_matrix", "galactic_from_icrs", "pm_galactic_from_icrs", "pm_icrs_from_galactic"]


@lru_cache(maxsize=1)
def icrs_to_galactic_matrix() -> np.ndarray:
    """3 x 3 rotation taking ICRS unit-vector components to galactic components."""
    from astropy.coordinates import ICRS, CartesianRepresentation, Galactic

    basis = CartesianRepresentation(np.eye(3))  # columns: x, y, z unit vectors
    gal = ICRS(basis).transform_to(Galactic()).cartesian
    m = np.stack([gal.x.value, gal.y.value, gal.z.value])  # row i: galactic axis i
    m.setflags(write=False)
    return m


def galactic_from_icrs(ra_deg, dec_deg) -> tuple[np.ndarray, np.ndarray]:
    """Galactic longitude and latitude (degrees, l in [0, 360)) of ICRS directions.

    Parameters
    ----------
    ra_deg, dec_deg : array_like
        ICRS right ascension and declination, degrees; broadcast together.

    Returns
    -------
    l_deg, b_deg : ndarray
    """
    ra = np.radians(np.asarray(ra_deg, dtype=float))
    dec = np.radians(np.asarray(dec_deg, dtype=float))
    cd = np.cos(dec)
    x, y, z = cd * np.cos(ra), cd * np.sin(ra), np.sin(dec)
    m = icrs_to_galactic_matrix()
    gx = m[0, 0] * x + m[0, 1] * y + m[0, 2] * z
    gy = m[1, 0] * x + m[1, 1] * y + m[1, 2] * z
    gz = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z
    l_deg = np.degrees(np.arctan2(gy, gx)) % 360.0
    b_deg = np.degrees(np.arctan2(gz, np.hypot(gx, gy)))
    return l_deg, b_deg


def _east_north(lon_rad, lat_rad) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors towards increasing longitude and latitude, (..., 3)."""
    sl, cl, sb, cb = np.sin(lon_rad), np.cos(lon_rad), np.sin(lat_rad), np.cos(lat_rad)
    east = np.stack([-sl, cl, np.zeros_like(sl)], axis=-1)
    north = np.stack([-sb * cl, -sb * sl, cb], axis=-1)
    return east, north


def pm_galactic_from_icrs(ra_deg, dec_deg, pmra, pmdec) -> tuple[np.ndarray, np.ndarray]:
    """Proper motion (mu_alpha*, mu_delta) at ICRS directions as galactic (mu_l*, mu_b), same unit.

    The proper motion is a tangent vector; both frames are fixed rotations of each other
    (:func:`icrs_to_galactic_matrix`), so the vector is rotated and projected on the galactic
    east and north directions. Agrees with ``SkyCoord(..., pm_ra_cosdec, pm_dec).galactic``
    to rounding (tests/test_galactic.py).
    """
    ra, dec = np.radians(np.asarray(ra_deg, float)), np.radians(np.asarray(dec_deg, float))
    east, north = _east_north(ra, dec)
    v = np.asarray(pmra, float)[..., None] * east + np.asarray(pmdec, float)[..., None] * north
    vg = v @ icrs_to_galactic_matrix().T
    l_deg, b_deg = galactic_from_icrs(ra_deg, dec_deg)
    ge, gn = _east_north(np.radians(l_deg), np.radians(b_deg))
    return np.sum(vg * ge, axis=-1), np.sum(vg * gn, axis=-1)


def pm_icrs_from_galactic(l_deg, b_deg, pml, pmb) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`pm_galactic_from_icrs`: (mu_l*, mu_b) at galactic directions as ICRS
    (mu_alpha*, mu_delta)."""
    lon, lat = np.radians(np.asarray(l_deg, float)), np.radians(np.asarray(b_deg, float))
    ge, gn = _east_north(lon, lat)
    vg = np.asarray(pml, float)[..., None] * ge + np.asarray(pmb, float)[..., None] * gn
    v = vg @ icrs_to_galactic_matrix()  # galactic -> ICRS: the transpose
    m = icrs_to_galactic_matrix()
    xyz_gal = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)
    xyz = xyz_gal @ m
    ra, dec = np.arctan2(xyz[..., 1], xyz[..., 0]), np.arcsin(np.clip(xyz[..., 2], -1.0, 1.0))
    e, n = _east_north(ra, dec)
    return np.sum(v * e, axis=-1), np.sum(v * n, axis=-1)
