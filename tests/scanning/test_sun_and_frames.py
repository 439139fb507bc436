"""Nominal Sun and the ecliptic frame against astropy (independent references)."""

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import (BarycentricMeanEcliptic, GeocentricMeanEcliptic, SkyCoord, get_sun)
from astropy.time import Time

from mcsweep.scanning.ephemeris import gaia_position_au, sun_position_au
from mcsweep.scanning.frames import ECLIPTIC_TO_ICRS, ICRS_TO_ECLIPTIC, local_north_east, unit_vector
from mcsweep.scanning.sun import nominal_sun_longitude

SUN_LONGITUDE_TOLERANCE_DEG = 0.01  # deg, accuracy of the Almanac's low-precision formula
GAIA_VIEW_TOLERANCE_DEG = 0.012  # deg, formula accuracy + the 0.0057 deg aberration (geometric view)
FRAME_TOLERANCE_ARCSEC = 0.1  # arcsec; ICRS frame bias (~0.02") is ignored on purpose
RATE_TOLERANCE_RAD_DAY = 1e-9  # rad/day
UNIT_TOLERANCE = 1e-14  # dimensionless


@pytest.fixture(scope="module")
def epochs():
    return Time(np.linspace(Time("2014-01-01", scale="tcb").jd, Time("2020-01-01", scale="tcb").jd, 97),
                format="jd", scale="tcb")


def _wrap_deg(x):
    return (np.asarray(x) + 180.0) % 360.0 - 180.0


def test_nominal_sun_matches_astropy_apparent_sun(epochs):
    # astropy's apparent geocentric Sun, on the mean ecliptic and equinox of J2000.
    sun = get_sun(epochs).transform_to(GeocentricMeanEcliptic(equinox="J2000", obstime=epochs))
    lon_rad, _ = nominal_sun_longitude(epochs.tcb.jd)
    diff = _wrap_deg(np.degrees(lon_rad) - sun.lon.deg)
    assert np.max(np.abs(diff)) < SUN_LONGITUDE_TOLERANCE_DEG


def test_nominal_sun_is_the_sun_seen_from_gaia(epochs):
    # Geometric direction Gaia -> Sun from the observer ephemeris, in ecliptic J2000.
    d = (sun_position_au(epochs) - gaia_position_au(epochs)) @ ICRS_TO_ECLIPTIC.T
    lon_gaia = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    lon_rad, _ = nominal_sun_longitude(epochs.tcb.jd)
    assert np.max(np.abs(_wrap_deg(np.degrees(lon_rad) - lon_gaia))) < GAIA_VIEW_TOLERANCE_DEG
    # and the Sun stays in the ecliptic plane as seen from Gaia (to the same accuracy)
    lat = np.degrees(np.arcsin(d[:, 2] / np.linalg.norm(d, axis=1)))
    assert np.max(np.abs(lat)) < GAIA_VIEW_TOLERANCE_DEG


def test_sun_longitude_rate_is_its_derivative(epochs):
    t = epochs.tcb.jd
    h = 1e-3  # day
    t_p, t_m = t + h, t - h  # divide by the represented step, not 2h (JD rounding ~5e-10 d)
    lon_p, _ = nominal_sun_longitude(t_p)
    lon_m, _ = nominal_sun_longitude(t_m)
    _, rate = nominal_sun_longitude(t)
    assert np.max(np.abs((lon_p - lon_m) / (t_p - t_m) - rate)) < RATE_TOLERANCE_RAD_DAY


def test_ecliptic_rotation_matches_astropy():
    rng = np.random.default_rng(3)
    ra = rng.uniform(0, 360, 50)
    dec = np.degrees(np.arcsin(rng.uniform(-1, 1, 50)))
    ecl = SkyCoord(ra=ra * u.deg, dec=dec * u.deg, frame="icrs").transform_to(
        BarycentricMeanEcliptic(equinox="J2000"))
    ours = unit_vector(ra, dec) @ ICRS_TO_ECLIPTIC.T
    theirs = unit_vector(ecl.lon.deg, ecl.lat.deg)
    sep_arcsec = np.degrees(np.linalg.norm(ours - theirs, axis=1)) * 3600
    assert np.max(sep_arcsec) < FRAME_TOLERANCE_ARCSEC
    np.testing.assert_allclose(ECLIPTIC_TO_ICRS @ ICRS_TO_ECLIPTIC, np.eye(3), atol=UNIT_TOLERANCE)


def test_local_triad_is_right_handed_and_points_north_east():
    ra, dec = np.array([0.0, 157.5, 300.0]), np.array([0.0, 0.0, -60.0])
    north, east = local_north_east(ra, dec)
    uvec = unit_vector(ra, dec)
    np.testing.assert_allclose(np.cross(uvec, east), north, atol=UNIT_TOLERANCE)
    # a small step along north raises the declination, along east the right ascension
    step = 1e-6
    for vec, coord in ((north, "dec"), (east, "ra")):
        p = uvec + step * vec
        c = SkyCoord(x=p[:, 0], y=p[:, 1], z=p[:, 2], representation_type="cartesian").spherical
        moved = (c.lat.deg - dec) if coord == "dec" else _wrap_deg(c.lon.deg - ra) * np.cos(np.radians(dec))
        np.testing.assert_allclose(moved, np.degrees(step), rtol=1e-4)
