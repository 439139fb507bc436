"""Numbers of field-of-view transits of the flown law against the published counts.

References (published, independent of our code):

* Gaia Collaboration, Prusti et al. 2016, A&A 595, A1, Table 1: end-of-mission (5-year)
  number of focal-plane passages per source, both fields of view combined, per band of
  ecliptic latitude (sin beta in steps of 0.05), "based on an assumed 6 % dead time";
  sky average 81. Its notes: Gaia DR1's 14 months correspond on average to 16 FoV
  transits.
* Gaia DR2 documentation, Sect. 1.3 (scanning law): the nominal five-year mission gives
  on average ~70 usable transits per star, assuming ~20 % of the transits collected on
  board give no useful information.

The closest reference would be the mean over Gaia EDR3's span in Lindegren et al. (2021,
A&A 649, A2); that figure was not within reach of this project's sources (README, scanning law),
so the flown law's counts are checked against these instead, over the 5-year mission and
DR1's span. Dead time enters as its mean fraction (the expected count), not as random blocks.
"""

import numpy as np
import pytest
from astropy.coordinates import SkyCoord
import astropy.units as u

from mcsweep.scanning import ScanningLaw, find_transits

#: Relative tolerance on a mean count: 10 %. The sampling error of our means
#: (20000 directions, ~1000 per ecliptic band, per-direction scatter ~20 %) is < 1 %.
COUNT_TOLERANCE = 0.10

#: Prusti et al. 2016, Table 1, column N_obs, for sin|beta| = 0.025, 0.075, ..., 0.975.
PRUSTI_TABLE1_NOBS = np.array([61, 61, 62, 62, 63, 65, 66, 68, 71, 75, 80, 87, 98, 122, 144, 106, 93, 85, 80, 75])
PRUSTI_TABLE1_SKY_AVERAGE = 81
PRUSTI_DEAD_TIME = 0.06
#: Prusti et al. 2016, Table 1 notes (DR1, 14 months) and the DR2 documentation (5 years),
#: both after the ~20 % of on-board transits that give no useful data (DR2 documentation).
DR1_FOV_TRANSITS, FIVE_YEAR_USABLE_TRANSITS, USABLE_FRACTION = 16, 70, 0.8

MISSION_START = "2014-07-25T10:30:00"  # start of routine operations (Prusti et al. 2016)
FIVE_YEARS_END = "2019-07-25T10:30:00"
DR1_END = "2015-09-16T00:00:00"        # conf/observations/dr1.yaml


@pytest.fixture(scope="module")
def sky():
    rng = np.random.default_rng(20160916)
    n = 20000
    ra = rng.uniform(0.0, 360.0, n)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    beta = SkyCoord(ra=ra * u.deg, dec=dec * u.deg).barycentrictrueecliptic.lat.rad
    return ra, dec, np.abs(np.sin(beta))


def _counts(sky, start, end):
    ra, dec, _ = sky
    tr = find_transits(ra, dec, start, end, law=ScanningLaw(), compact=True)
    return np.bincount(tr["source_index"].to_numpy(), minlength=ra.size)


@pytest.fixture(scope="module")
def five_years(sky):
    return _counts(sky, MISSION_START, FIVE_YEARS_END)


def test_five_year_counts_per_ecliptic_band_match_prusti_table1(sky, five_years):
    band = np.minimum((sky[2] / 0.05).astype(int), 19)
    ours = (1.0 - PRUSTI_DEAD_TIME) * np.array([five_years[band == k].mean() for k in range(20)])
    rel = ours / PRUSTI_TABLE1_NOBS - 1.0
    assert np.all(np.abs(rel) < COUNT_TOLERANCE), np.round(rel, 3)
    # the shape that matters for priors: the maximum at 45 deg and the deficit in the ecliptic
    assert np.argmax(ours) == np.argmax(PRUSTI_TABLE1_NOBS)
    sky_mean = (1.0 - PRUSTI_DEAD_TIME) * five_years.mean()
    assert abs(sky_mean / PRUSTI_TABLE1_SKY_AVERAGE - 1.0) < COUNT_TOLERANCE


def test_five_year_usable_transits_match_the_dr2_documentation(five_years):
    assert abs(USABLE_FRACTION * five_years.mean() / FIVE_YEAR_USABLE_TRANSITS - 1.0) < COUNT_TOLERANCE


def test_dr1_span_transits_match_prusti_table1_notes(sky):
    mean = USABLE_FRACTION * _counts(sky, MISSION_START, DR1_END).mean()
    assert abs(mean / DR1_FOV_TRANSITS - 1.0) < COUNT_TOLERANCE
