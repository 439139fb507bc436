"""Fixed frames used by the scanning law: ecliptic J2000 <-> ICRS, unit vectors, local triad.

The scanning law lives in the ecliptic frame of J2000 (the nominal Sun's longitude is
measured there). Positions of stars are ICRS. The two differ by a rotation about the
common x axis (the equinox) by the obliquity of the ecliptic at J2000; the ~20 mas
frame bias between ICRS and the dynamical J2000 frame is ignored (it is five orders
of magnitude below the 0.4 deg width of the fields of view).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "OBLIQUITY_J2000_ARCSEC",
    "ICRS_TO_ECLIPTIC",
    "ECLIPTIC_TO_ICRS",
    "unit_vector",
    "local_north_east",
    "tangent_triad",
]

#: Mean obliquity of the ecliptic at J2000.0 (IAU 2006 precession, Capitaine et al. 2003) [arcsec].
OBLIQUITY_J2000_ARCSEC = 84381.406

_eps = np.deg2rad(OBLIQUITY_J2000_ARCSEC / 3600.0)
#: Rotation matrix taking ICRS vector components to ecliptic-J2000 components.
ICRS_TO_ECLIPTIC = np.array(
    [
        [1.0, 0.0, 0.0],
        [0.0, np.cos(_eps), np.sin(_eps)],
        [0.0, -np.sin(_eps), np.cos(_eps)],
    ]
)
ICRS_TO_ECLIPTIC.setflags(write=False)
#: Rotation matrix taking ecliptic-J2000 components to ICRS components.
ECLIPTIC_TO_ICRS = ICRS_TO_ECLIPTIC.T.copy()
ECLIPTIC_TO_ICRS.setflags(write=False)


def unit_vector(lon_deg, lat_deg) -> np.ndarray:
    """Cartesian unit vector of spherical coordinates.

    Parameters
    ----------
    lon_deg, lat_deg : array_like
        Longitude (e.g. right ascension) and latitude (e.g. declination) [deg].

    Returns
    -------
    ndarray, shape ``broadcast(lon, lat).shape + (3,)``
    """
    lon = np.deg2rad(np.asarray(lon_deg, dtype=float))
    lat = np.deg2rad(np.asarray(lat_deg, dtype=float))
    cos_lat = np.cos(lat)
    return np.stack(np.broadcast_arrays(cos_lat * np.cos(lon), cos_lat * np.sin(lon), np.sin(lat)), axis=-1)


def tangent_triad(lon_deg, lat_deg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors towards local east (p), local north (q) and the direction (r).

    The normal triad of Lindegren et al. (2012, A&A 538, A78, Eq. 1), the one
    implementation in the package (the design matrix, the transit search and the cones
    of the population all use it).

    Parameters
    ----------
    lon_deg, lat_deg : array_like
        Longitude (e.g. right ascension, Galactic l) and latitude (declination, b) [deg];
        broadcast together.

    Returns
    -------
    p, q, r : ndarray, shape ``broadcast_shape + (3,)``
        Components in the axes of the frame of ``lon, lat`` (ICRS for ra, dec).
    """
    lon = np.deg2rad(np.asarray(lon_deg, dtype=float))
    lat = np.deg2rad(np.asarray(lat_deg, dtype=float))
    lon, lat = np.broadcast_arrays(lon, lat)
    sa, ca, sd, cd = np.sin(lon), np.cos(lon), np.sin(lat), np.cos(lat)
    p = np.stack([-sa, ca, np.zeros_like(sa)], axis=-1)
    q = np.stack([-sd * ca, -sd * sa, cd], axis=-1)
    r = np.stack([cd * ca, cd * sa, sd], axis=-1)
    return p, q, r


def local_north_east(ra_deg, dec_deg) -> tuple[np.ndarray, np.ndarray]:
    """Local north and east unit vectors (ICRS components) at the given directions.

    Parameters
    ----------
    ra_deg, dec_deg : array_like
        Right ascension and declination [deg].

    Returns
    -------
    north, east : ndarray, shape ``(..., 3)``
        ``north`` points towards increasing declination, ``east`` towards increasing
        right ascension (:func:`tangent_triad`'s q and p).
    """
    east, north, _ = tangent_triad(ra_deg, dec_deg)
    return north, east
