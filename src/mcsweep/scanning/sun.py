"""Longitude of the nominal Sun that drives the scanning law.

The nominal scanning law is defined relative to a *nominal* Sun, an analytical
approximation of the Sun's apparent direction, not the ephemeris Sun. We use the
low-precision solar formula of the Astronomical Almanac (Section C, "Low-precision
formulas for the Sun", accuracy 0.01 deg for 1950-2050) in the form adopted for
Gaia's nominal scanning law (de Bruijne et al. 2010, IAU Symp. 261, 331):

* the mean longitude rate is 0.98560903 deg/day instead of the Almanac's
  0.9856474 deg/day, i.e. the general precession (1.397 deg per century) is removed,
  so the longitude refers to the fixed ecliptic and equinox of J2000;
* the constant aberration (-20.49122 arcsec) is applied to the mean longitude, so the
  direction is the apparent one;
* the equation of centre is ``2 e sin g + 5/4 e**2 sin 2g`` with e = 0.01671
  (= 1.915 deg sin g + 0.020 deg sin 2g of the Almanac).

The time argument is days from J2000.0 in TCB. The direction seen from Gaia differs
from this formula by less than 0.01 deg (tested against astropy's ephemeris in
``tests/scanning/test_sun.py``).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "JD_J2000",
    "SUN_MEAN_LONGITUDE_J2000_DEG",
    "SUN_MEAN_LONGITUDE_RATE_DEG_DAY",
    "SUN_MEAN_ANOMALY_J2000_DEG",
    "SUN_MEAN_ANOMALY_RATE_DEG_DAY",
    "EARTH_ORBIT_ECCENTRICITY",
    "ABERRATION_CONSTANT_ARCSEC",
    "nominal_sun_longitude",
]

#: Julian date of the epoch J2000.0 (2000-01-01T12:00:00).
JD_J2000 = 2451545.0
#: Mean longitude of the Sun at J2000.0, ecliptic and equinox of J2000 [deg].
SUN_MEAN_LONGITUDE_J2000_DEG = 280.4665
#: Rate of the mean longitude, precession removed [deg/day].
SUN_MEAN_LONGITUDE_RATE_DEG_DAY = 0.98560903
#: Mean anomaly of the Sun at J2000.0 [deg].
SUN_MEAN_ANOMALY_J2000_DEG = 357.529
#: Rate of the mean anomaly [deg/day].
SUN_MEAN_ANOMALY_RATE_DEG_DAY = 0.98560020
#: Eccentricity of the Earth's orbit at J2000.0.
EARTH_ORBIT_ECCENTRICITY = 0.01671
#: Constant of aberration [arcsec].
ABERRATION_CONSTANT_ARCSEC = 20.49122


def nominal_sun_longitude(tcb_jd):
    """Ecliptic longitude of the nominal Sun and its rate.

    Parameters
    ----------
    tcb_jd : array_like
        Epochs as Julian dates in TCB [day].

    Returns
    -------
    lon_rad : ndarray
        Longitude in the ecliptic of J2000 [rad], not wrapped (it increases
        monotonically, by 2 pi per year).
    rate_rad_day : ndarray
        Its time derivative [rad/day].
    """
    d = np.asarray(tcb_jd, dtype=float) - JD_J2000
    e = EARTH_ORBIT_ECCENTRICITY
    mean_lon = np.deg2rad(
        SUN_MEAN_LONGITUDE_J2000_DEG - ABERRATION_CONSTANT_ARCSEC / 3600.0
        + SUN_MEAN_LONGITUDE_RATE_DEG_DAY * d
    )
    g = np.deg2rad(SUN_MEAN_ANOMALY_J2000_DEG + SUN_MEAN_ANOMALY_RATE_DEG_DAY * d)
    sin_g, cos_g = np.sin(g), np.cos(g)
    lon = mean_lon + 2.0 * e * sin_g + 1.25 * e * e * 2.0 * sin_g * cos_g
    g_dot = np.deg2rad(SUN_MEAN_ANOMALY_RATE_DEG_DAY)
    rate = np.deg2rad(SUN_MEAN_LONGITUDE_RATE_DEG_DAY) + g_dot * (
        2.0 * e * cos_g + 2.5 * e * e * (cos_g * cos_g - sin_g * sin_g)
    )
    return lon, rate
