"""Directions recovered from AL parallax factors: simulated scans and the vendored DR4 sample."""

from importlib import resources

import numpy as np
import pandas as pd
import pytest
from astropy import units as u
from astropy.coordinates import SkyCoord

from mcsweep.astrometry.design import JULIAN_YEAR_DAYS, design_matrix
from mcsweep.astrometry.direction import (
    direction_from_parallax_factors,
    directions_of_sources,
    parallax_factors_al,
    sample_sources_table,
)
from mcsweep.errors import UserInputError
from mcsweep.scanning import find_transits
from mcsweep.scanning.frames import ECLIPTIC_TO_ICRS

#: Test directions (ICRS ra, dec [deg]): Table 1's star, mid latitudes, near both poles.
DIRECTIONS = [(157.5, 0.0), (45.0, 60.0), (270.0, -30.0), (10.0, 85.0), (300.0, -88.0)]
#: Two years of the flown scanning law (TCB).
SPAN = ("2014-08-25", "2016-08-25")

#: Separation allowed when the factors are made with the fit's own observer model: only
#: rounding and the least-squares convergence remain (measured < 1e-15 deg).
SELF_CONSISTENT_TOL_DEG = 1e-9
#: ... and the residual RMS of the factors then.
SELF_CONSISTENT_RMS = 1e-9
#: Separation allowed when the factors hold an orbit about L2 that the fit's model lacks
#: (the real files' case, module notes of mcsweep.astrometry.direction): a direction
#: error of x rad changes P_AL by ~x, so an orbit of a few 1e-3 au biases it by a few
#: 1e-3 rad; measured 0.02-0.16 deg here (two years), up to 0.2 deg with five years.
L2_MODEL_TOL_DEG = 0.3
#: Lissajous-like offset added to Gaia's position: semi-amplitudes [au] radial (Sun-Gaia
#: line), in the ecliptic across it, and out of the ecliptic (Gaia's orbit about L2 is
#: ~263 000 x 707 000 x 370 000 km in full extent), periods [d] ~ 180 d.
LISSAJOUS_AU = (0.9e-3, 2.4e-3, 1.2e-3)
LISSAJOUS_PERIODS_D = (178.0, 178.0, 184.0)

#: Bound on the residual RMS of P_AL at every sample source's recovered direction. The
#: files' factors hold Gaia's real orbit; ours is L2 itself, ~1e-3 au off, so the residual
#: is ~1e-3 (measured 7.0e-4 - 1.1e-3 over the ten sources, 6e-4 - 1.3e-3 in the
#: simulation with a Lissajous-like orbit); about twice the worst, while a wrong direction
#: leaves residuals of >= 0.03 (the best grid direction with the factors' sign flipped:
#: 0.034 - 0.32; a spurious local minimum near a pole: 0.09).
SAMPLE_RMS_BOUND = 2.5e-3
#: Two sample sources are Hipparcos stars (G, parallax and proper motion agree with
#: AGIS's results): source 7 = HIP 983, source 9 = HIP 114046 (Lacaille 9352). ICRS
#: position at J1991.25 [deg] and proper motion [mas/yr] from the new reduction (van
#: Leeuwen 2007, CDS I/311), propagated linearly to the sample's mid-epoch.
HIPPARCOS_MATCHES = {7: (3.041455, -17.938218, 55.37, -24.95), 9: (346.446521, -35.856297, 6768.20, 1327.52)}
SAMPLE_MID_EPOCH_YR = 2017.0
#: Separation allowed from those positions (measured 0.072 and 0.097 deg: the L2 model).
HIPPARCOS_TOL_DEG = 0.2
#: Rounding of the CSV's columns (4 decimals for ra/dec, 3 significant digits for the RMS).
CSV_ATOL_DEG = 1e-4


def _separation_deg(ra1, dec1, ra2, dec2) -> float:
    return float(SkyCoord(ra1 * u.deg, dec1 * u.deg).separation(SkyCoord(ra2 * u.deg, dec2 * u.deg)).deg)


@pytest.fixture(scope="module")
def simulated():
    """Transits of DIRECTIONS with their exact P_AL from the simulator's observer positions."""
    ra, dec = np.array(DIRECTIONS).T
    tr = find_transits(ra, dec, *SPAN)
    i = tr["source_index"].to_numpy()
    obs = tr[["obs_x_au", "obs_y_au", "obs_z_au"]].to_numpy()
    tr["pfac"] = parallax_factors_al(ra[i], dec[i], tr["scan_angle_deg"].to_numpy(), obs)
    offset = _lissajous_like_au(tr["tcb_jd"].to_numpy(), obs)
    tr["pfac_lissajous"] = parallax_factors_al(ra[i], dec[i], tr["scan_angle_deg"].to_numpy(), obs + offset)
    return tr


def _lissajous_like_au(tcb_jd, obs_au):
    """A Lissajous-like offset of Gaia from L2 (LISSAJOUS_AU, LISSAJOUS_PERIODS_D), (k, 3) au."""
    radial = obs_au / np.linalg.norm(obs_au, axis=1, keepdims=True)
    pole = ECLIPTIC_TO_ICRS[:, 2]
    across = np.cross(pole, radial)
    across /= np.linalg.norm(across, axis=1, keepdims=True)
    w = 2 * np.pi * (tcb_jd - tcb_jd.min())[:, None] / np.array(LISSAJOUS_PERIODS_D)
    a_r, a_y, a_z = LISSAJOUS_AU
    return a_r * np.cos(w[:, :1]) * radial + a_y * np.sin(w[:, 1:2]) * across + a_z * np.sin(w[:, 2:] + 1.0) * pole


def test_parallax_factor_is_the_design_matrix_parallax_column(simulated):
    # The sign convention of the files' P_AL is that of Eq. 1's parallax column.
    ra, dec = np.array(DIRECTIONS).T
    tr = simulated[simulated["source_index"] == 1]
    obs = tr[["obs_x_au", "obs_y_au", "obs_z_au"]].to_numpy()[None]
    t_yr = (tr["tcb_jd"].to_numpy()[None] - tr["tcb_jd"].mean()) / JULIAN_YEAR_DAYS
    a = design_matrix(ra[1:2], dec[1:2], t_yr, tr["scan_angle_deg"].to_numpy()[None], obs, sigma_al_mas=1.0)
    np.testing.assert_allclose(a[0, :, 2], tr["pfac"].to_numpy(), rtol=0, atol=1e-14)


@pytest.mark.parametrize("column, tol_deg, rms_bound", [
    ("pfac", SELF_CONSISTENT_TOL_DEG, SELF_CONSISTENT_RMS),  # the model's own orbit: exact
    ("pfac_lissajous", L2_MODEL_TOL_DEG, SAMPLE_RMS_BOUND),  # an orbit about L2 the model lacks
])
@pytest.mark.parametrize("index", range(len(DIRECTIONS)))
def test_recovers_simulated_direction(simulated, index, column, tol_deg, rms_bound):
    tr = simulated[simulated["source_index"] == index]
    ra, dec, rms = direction_from_parallax_factors(tr["tcb_jd"], tr["scan_angle_deg"], tr[column])
    assert _separation_deg(ra, dec, *DIRECTIONS[index]) < tol_deg
    assert rms < rms_bound
    assert 0.0 <= ra < 360.0


def test_directions_of_sources_groups_by_source(simulated):
    shuffled = simulated.sample(frac=1.0, random_state=np.random.default_rng(5))
    ids = shuffled["source_index"].to_numpy() * 1000 + 7
    df = directions_of_sources(ids, shuffled["tcb_jd"], shuffled["scan_angle_deg"], shuffled["pfac"])
    assert list(df.columns) == ["source_id", "ra", "dec", "parallax_factor_rms"]
    assert df["source_id"].tolist() == [i * 1000 + 7 for i in range(len(DIRECTIONS))]
    assert df["source_id"].dtype == np.int64
    for row, (ra, dec) in zip(df.itertuples(), DIRECTIONS):
        assert _separation_deg(row.ra, row.dec, ra, dec) < SELF_CONSISTENT_TOL_DEG


def test_refuses_bad_input():
    with pytest.raises(UserInputError, match="not enough"):
        direction_from_parallax_factors([2457000.0, 2457001.0], [10.0, 20.0], [0.1, 0.2])
    with pytest.raises(UserInputError, match="equal length"):
        direction_from_parallax_factors([2457000.0, 2457001.0, 2457002.0], [10.0, 20.0], [0.1, 0.2, 0.3])
    with pytest.raises(UserInputError, match="non-finite"):
        direction_from_parallax_factors([2457000.0, 2457001.0, 2457002.0], [10.0, np.nan, 1.0], [0.1, 0.2, 0.3])


@pytest.fixture(scope="module")
def sample():
    return sample_sources_table()


def test_sample_directions_reproduce_parallax_factors(sample):
    assert len(sample) == 10
    assert (sample["parallax_factor_rms_direction"] < SAMPLE_RMS_BOUND).all(), sample
    assert sample["phot_g_mean_mag"].notna().all()


def test_sample_hipparcos_stars(sample):
    by_id = sample.set_index("source_id")
    dt_yr = SAMPLE_MID_EPOCH_YR - 1991.25
    for sid, (ra, dec, pmra, pmdec) in HIPPARCOS_MATCHES.items():
        ra_now = ra + pmra * dt_yr / 3.6e6 / np.cos(np.radians(dec))
        dec_now = dec + pmdec * dt_yr / 3.6e6
        assert _separation_deg(by_id.loc[sid, "ra"], by_id.loc[sid, "dec"], ra_now, dec_now) < HIPPARCOS_TOL_DEG


def test_vendored_csv_is_up_to_date(sample):
    path = resources.files("mcsweep").joinpath("data", "epoch_astrometry", "sample_sources.csv")
    with path.open("r") as fh:
        vendored = pd.read_csv(fh, comment="#")
    assert list(vendored.columns) == ["source_id", "ra", "dec", "phot_g_mean_mag", "parallax_factor_rms_direction"]
    assert vendored["source_id"].tolist() == sample["source_id"].tolist()
    for col in ("ra", "dec", "phot_g_mean_mag"):
        np.testing.assert_allclose(vendored[col], sample[col], rtol=0, atol=CSV_ATOL_DEG)
    np.testing.assert_allclose(vendored["parallax_factor_rms_direction"], sample["parallax_factor_rms_direction"],
                               rtol=5e-3)
