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

__all__ = ["icrs_to_galactic_matrix", "galactic_from_icrs", "icrs_from_galactic", "unit_vector", "pm_galactic_from_icrs",
           "pm_icrs_from_galactic"]


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


def unit_vector(lon_deg, lat_deg) -> np.ndarray:
    """Cartesian unit vectors (..., 3) of directions given as longitude and latitude in degrees
    (in the frame the angles are in)."""
    lon, lat = np.radians(lon_deg), np.radians(lat_deg)
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)


def _east_north(lon_rad, lat_rad) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors towards increasing longitude and latitude, (..., 3)."""
    sl, cl, sb, cb = np.sin(lon_rad), np.cos(lon_rad), np.sin(lat_rad), np.cos(lat_rad)
    return np.stack([-sl, cl, np.zeros_like(sl)], axis=-1), np.stack([-sb * cl, -sb * sl, cb], axis=-1)


def icrs_from_galactic(l_deg, b_deg) -> tuple[np.ndarray, np.ndarray]:
    """ICRS (ra, dec) in degrees of galactic directions (the rotation of :func:`icrs_to_galactic_matrix`,
    transposed)."""
    xyz = unit_vector(np.asarray(l_deg, float), np.asarray(b_deg, float)) @ icrs_to_galactic_matrix()
    ra = np.degrees(np.arctan2(xyz[..., 1], xyz[..., 0])) % 360.0
    dec = np.degrees(np.arctan2(xyz[..., 2], np.hypot(xyz[..., 0], xyz[..., 1])))
    return ra, dec


def pm_galactic_from_icrs(ra_deg, dec_deg, pmra, pmdec) -> tuple[np.ndarray, np.ndarray]:
    """Proper motion (mu_alpha*, mu_delta) at ICRS directions as galactic (mu_l*, mu_b), same unit.

    A proper motion is a tangent vector of the sphere and the frames are a fixed rotation of
    each other (:func:`icrs_to_galactic_matrix`): the vector built on the ICRS east and north
    directions is rotated and projected on the galactic east and north directions at the same
    point. Agrees with ``SkyCoord(..., pm_ra_cosdec, pm_dec).galactic`` to rounding
    (tests/test_galactic.py).
    """
    east, north = _east_north(np.radians(np.asarray(ra_deg, float)), np.radians(np.asarray(dec_deg, float)))
    v = (np.asarray(pmra, float)[..., None] * east + np.asarray(pmdec, float)[..., None] * north) \
        @ icrs_to_galactic_matrix().T
    l_deg, b_deg = galactic_from_icrs(ra_deg, dec_deg)
    ge, gn = _east_north(np.radians(l_deg), np.radians(b_deg))
    return np.sum(v * ge, axis=-1), np.sum(v * gn, axis=-1)


def pm_icrs_from_galactic(l_deg, b_deg, pml, pmb) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`pm_galactic_from_icrs`: (mu_l*, mu_b) at galactic directions as ICRS
    (mu_alpha*, mu_delta), same unit."""
    l_deg, b_deg = np.asarray(l_deg, float), np.asarray(b_deg, float)
    ge, gn = _east_north(np.radians(l_deg), np.radians(b_deg))
    v = (np.asarray(pml, float)[..., None] * ge + np.asarray(pmb, float)[..., None] * gn) @ icrs_to_galactic_matrix()
    ra, dec = icrs_from_galactic(l_deg, b_deg)
    e, n = _east_north(np.radians(ra), np.radians(dec))
    return np.sum(v * e, axis=-1), np.sum(v * n, axis=-1)
