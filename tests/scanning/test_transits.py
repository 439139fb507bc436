"""FoV transits: fast search vs brute force, conventions vs astropy, sky statistics, options."""

import math

import numpy as np
import pandas as pd
import pytest
from astropy import units as u
from astropy.coordinates import SkyCoord
from astropy.time import Time

import mcsweep.scanning.transits as transits_module
from mcsweep.errors import UserInputError
from mcsweep.scanning import TRANSIT_COLUMNS, ScanningLaw, find_transits, gaia_position_au, observer_position_au
from mcsweep.scanning.attitude import attitude_for
from mcsweep.scanning.frames import ECLIPTIC_TO_ICRS
from mcsweep.scanning.reference import reference_transits

REF_TIME_TOLERANCE_S = 0.05  # s; brute force interpolates linearly over a 30 s step
REF_ANGLE_TOLERANCE_DEG = 1e-4  # deg (psi and zeta)
PA_TOLERANCE_DEG = 1e-4  # deg, psi (spin axis taken < 2 s from the transit) vs astropy
FOV_LAG_TOLERANCE_S = 5.0  # s, deviation of the P -> F lag from Gamma / omega_z
OBS_TOLERANCE_AU = 1e-12  # au
CONVERGENCE_TIME_S = 1e-3  # s, residual of phi(t) = FoV azimuth at the returned time, as time
CONVERGENCE_ZETA_DEG = 1e-8  # deg, returned zeta vs the attitude at the returned time
MEAN_COUNT_RANGE_5YR = (85.0, 90.0)  # FoV transits per star over 5 years, no dead time (acceptance range)
DILUTION_TOLERANCE = 0.005  # absolute, kept fraction (> 5 sigma for ~1e5 transits)
DEAD_TIME_TOLERANCE = 0.03  # absolute, lost fraction of transits

START_JD = 2457023.5  # 2015-01-01 TCB
FIVE_YEARS_D = 5 * 365.25


def _random_sky(n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))


def _ecliptic_latitude_deg(ra, dec):
    c = SkyCoord(ra=ra * u.deg, dec=dec * u.deg).barycentricmeanecliptic
    return c.lat.deg


@pytest.fixture(scope="module")
def sky_5yr():
    ra, dec = _random_sky(4000, seed=101)
    return ra, dec, find_transits(ra, dec, START_JD, START_JD + FIVE_YEARS_D)


def test_fast_search_equals_brute_force_reference():
    ra, dec = _random_sky(16, seed=5)
    # add directions at the ecliptic poles, on the ecliptic and at |beta| = 45 deg
    ecl = SkyCoord(lon=[0, 80, 200, 300, 33] * u.deg, lat=[90, -90, 0, 45, -45] * u.deg,
                   frame="barycentricmeanecliptic").icrs
    ra, dec = np.r_[ra, ecl.ra.deg], np.r_[dec, ecl.dec.deg]
    start, end = START_JD + 100.0, START_JD + 200.0
    fast = find_transits(ra, dec, start, end)
    ref = reference_transits(ra, dec, start, end, step_s=30.0)
    assert len(fast) == len(ref) > 50
    assert (fast["source_index"].to_numpy() == ref["source_index"].to_numpy()).all()
    assert (fast["fov"].astype(str).to_numpy() == ref["fov"].to_numpy()).all()
    assert np.max(np.abs(fast["tcb_jd"].to_numpy() - ref["tcb_jd"].to_numpy())) * 86400 < REF_TIME_TOLERANCE_S
    for col in ("scan_angle_deg", "ac_offset_deg"):
        d = (fast[col].to_numpy() - ref[col].to_numpy() + 180) % 360 - 180
        assert np.max(np.abs(d)) < REF_ANGLE_TOLERANCE_DEG


def test_output_columns_order_and_dtypes(sky_5yr):
    df = sky_5yr[2]
    assert tuple(df.columns) == TRANSIT_COLUMNS
    assert isinstance(df["fov"].dtype, pd.CategoricalDtype) and set(df["fov"].unique()) == {"P", "F"}
    key = df["source_index"].to_numpy() * 1e4 + (df["tcb_jd"].to_numpy() - START_JD)
    assert np.all(np.diff(key) > 0)  # sorted by (source, time), no duplicates
    assert df["scan_angle_deg"].between(0, 360, inclusive="left").all()
    assert df["tcb_jd"].between(START_JD, START_JD + FIVE_YEARS_D, inclusive="left").all()


def test_transits_lie_within_the_acceptance_and_at_the_fov_azimuth(sky_5yr):
    ra, dec, df = sky_5yr
    sub = df.iloc[::97]
    law = ScanningLaw()
    a_icrs = np.einsum("ij,tjk->tik", ECLIPTIC_TO_ICRS, attitude_for(law).matrix(sub["tcb_jd"].to_numpy()))
    c = SkyCoord(ra=ra[sub["source_index"]] * u.deg, dec=dec[sub["source_index"]] * u.deg)
    uvec = c.cartesian.xyz.value.T
    srs = np.einsum("tik,ti->tk", a_icrs, uvec)
    phi = np.degrees(np.arctan2(srs[:, 1], srs[:, 0]))
    expected = np.where(sub["fov"] == "P", 1, -1) * law.basic_angle_deg / 2
    assert np.max(np.abs(phi - expected)) < REF_ANGLE_TOLERANCE_DEG
    zeta = np.degrees(np.arcsin(srs[:, 2]))
    np.testing.assert_allclose(zeta, sub["ac_offset_deg"], atol=REF_ANGLE_TOLERANCE_DEG)
    for fov, (lo, hi) in (("P", law.ac_limits_p_deg), ("F", law.ac_limits_f_deg)):
        z = df.loc[df["fov"] == fov, "ac_offset_deg"]
        assert z.min() > lo and z.max() < hi
        assert z.min() < lo + 0.01 and z.max() > hi - 0.01  # the whole acceptance is used


def test_every_transit_time_is_converged(sky_5yr):
    # All ~350 000 transits: evaluate the attitude at the returned time (no search involved).
    ra, dec, df = sky_5yr
    law = ScanningLaw()
    u_ecl = SkyCoord(ra=ra * u.deg, dec=dec * u.deg).cartesian.xyz.value.T @ ECLIPTIC_TO_ICRS
    psi_w, z, omega = attitude_for(law).srs_components(u_ecl[df["source_index"]], df["tcb_jd"].to_numpy())
    azimuth = np.where(df["fov"] == "P", 0.5, -0.5) * math.radians(law.basic_angle_deg)
    resid = np.mod(psi_w - omega - azimuth + math.pi, 2 * math.pi) - math.pi
    assert np.max(np.abs(resid)) / law.spin_rate_rad_day * 86400 < CONVERGENCE_TIME_S
    assert np.max(np.abs(np.degrees(np.arcsin(z)) - df["ac_offset_deg"])) < CONVERGENCE_ZETA_DEG


def test_scan_angle_is_astropy_position_angle_of_the_scan_direction(sky_5yr):
    # psi = position angle (east of north) of d = z x u, the direction in which the FoV
    # moves across the star; checked with astropy's position_angle of a displaced point.
    ra, dec, df = sky_5yr
    sub = df.iloc[::211]
    z = attitude_for(ScanningLaw()).spin_axis(sub["tcb_jd"].to_numpy()) @ ECLIPTIC_TO_ICRS.T
    star = SkyCoord(ra=ra[sub["source_index"]] * u.deg, dec=dec[sub["source_index"]] * u.deg)
    uvec = star.cartesian.xyz.value.T
    p = uvec + 1e-6 * np.cross(z, uvec)
    moved = SkyCoord(x=p[:, 0], y=p[:, 1], z=p[:, 2], representation_type="cartesian")
    pa = star.position_angle(moved).deg
    d = (pa - sub["scan_angle_deg"].to_numpy() + 180) % 360 - 180
    assert np.max(np.abs(d)) < PA_TOLERANCE_DEG


def test_following_fov_trails_preceding_by_gamma_over_omega(sky_5yr):
    df = sky_5yr[2]
    law = ScanningLaw()
    src = df["source_index"].to_numpy()
    fov, t = df["fov"].astype(str).to_numpy(), df["tcb_jd"].to_numpy()
    # A P transit followed, within half a spin, by an F transit of the same source: the
    # same spin revolution seen by both FoVs.
    pair = ((src[1:] == src[:-1]) & (fov[:-1] == "P") & (fov[1:] == "F")
            & (t[1:] - t[:-1] < 0.5 * law.spin_period_days))
    assert pair.sum() > 0.3 * len(df)
    lag = (t[1:] - t[:-1])[pair]
    assert law.fov_lag_days * 24 == pytest.approx(1.776, abs=0.001)  # Gamma / omega_z ~ 1.77 h
    assert np.max(np.abs(lag - law.fov_lag_days)) * 86400 < FOV_LAG_TOLERANCE_S
    # Both FoVs of one spin always fall in one group (visit).
    grp = df["group"].to_numpy()
    assert (grp[1:][pair] == grp[:-1][pair]).all()


def test_five_year_counts_over_the_sky(sky_5yr):
    ra, dec, df = sky_5yr
    counts = np.bincount(df["source_index"], minlength=ra.size)
    assert MEAN_COUNT_RANGE_5YR[0] < counts.mean() < MEAN_COUNT_RANGE_5YR[1]
    beta = np.abs(_ecliptic_latitude_deg(ra, dec))
    edges = np.arange(0, 91, 10)
    means = np.array([counts[(beta >= a) & (beta < b)].mean() for a, b in zip(edges[:-1], edges[1:])])
    # Most transits near |beta| = 45 deg, fewest near the ecliptic.
    assert 30 <= edges[np.argmax(means)] <= 50
    assert np.argmin(means) == 0
    assert means.max() > 1.5 * means[0]


def test_observer_position_is_the_ephemeris_at_the_transit(sky_5yr):
    df = sky_5yr[2].iloc[::50]
    obs = df[["obs_x_au", "obs_y_au", "obs_z_au"]].to_numpy()
    np.testing.assert_allclose(obs, gaia_position_au(df["tcb_jd"].to_numpy()), atol=OBS_TOLERANCE_AU, rtol=0)


def test_astropy_time_bounds_and_iso_strings_agree():
    a = find_transits([10.0, 200.0], [20.0, -30.0], Time("2015-03-01", scale="tcb"),
                      Time("2015-09-01", scale="tcb"))
    b = find_transits([10.0, 200.0], [20.0, -30.0], "2015-03-01", "2015-09-01")
    pd.testing.assert_frame_equal(a, b)
    # A UTC bound is converted, not taken as TCB: TCB - UTC = (TT - UTC = 67.184 s)
    # + (TCB - TT = 1.55e-8 x time since 1977.0 = 18.7 s) in March 2015.
    c = find_transits([10.0], [20.0], Time("2015-03-01", scale="utc"), Time("2015-09-01", scale="utc"))
    assert len(c) > 0
    tcb_minus_utc_s = (c.attrs["start_tcb_jd"] - Time("2015-03-01", scale="tcb").jd) * 86400
    assert tcb_minus_utc_s == pytest.approx(85.9, abs=0.2)


def test_compact_output_holds_the_same_transits():
    ra, dec = _random_sky(50, seed=9)
    full = find_transits(ra, dec, START_JD, START_JD + 200)
    small = find_transits(ra, dec, START_JD, START_JD + 200, compact=True)
    assert small["source_index"].dtype == np.int32 and "obs_x_au" not in small
    np.testing.assert_array_equal(full["tcb_jd"], small["tcb_jd"])
    np.testing.assert_allclose(full["scan_angle_deg"], small["scan_angle_deg"], atol=1e-4)
    # The observer of compact output comes from the same ephemeris table, at tcb_jd.
    np.testing.assert_array_equal(observer_position_au(small), observer_position_au(full))


def test_no_transits_in_a_short_interval_gives_an_empty_frame():
    df = find_transits([0.0], [89.0], START_JD, START_JD + 0.01)
    assert tuple(df.columns) == TRANSIT_COLUMNS and len(df) == 0


# ---------------------------------------------------------------- dead time, dilution, determinism
def _options_run(ra, dec, seed, **kw):
    return find_transits(ra, dec, START_JD, START_JD + 365.25, dead_time_fraction=0.2, dilution=0.5,
                         rng=np.random.default_rng(seed), **kw)


def test_dilution_keeps_the_expected_fraction(sky_5yr):
    ra, dec, full = sky_5yr
    diluted = find_transits(ra, dec, START_JD, START_JD + FIVE_YEARS_D, dilution=0.95,
                            rng=np.random.default_rng(1))
    assert len(diluted) / len(full) == pytest.approx(0.05, abs=DILUTION_TOLERANCE)
    # kept transits are a subset of the full list
    key = ["source_index", "tcb_jd", "fov"]
    merged = diluted[key].merge(full[key], how="left", indicator=True)
    assert (merged["_merge"] == "both").all()


def test_dead_time_removes_the_expected_fraction(sky_5yr):
    ra, dec, full = sky_5yr
    dead = find_transits(ra, dec, START_JD, START_JD + FIVE_YEARS_D, dead_time_fraction=0.2,
                         rng=np.random.default_rng(2))
    assert 1 - len(dead) / len(full) == pytest.approx(0.2, abs=DEAD_TIME_TOLERANCE)


def test_same_seed_same_result_and_different_seed_different_result():
    ra, dec = _random_sky(300, seed=4)
    a, b, c = _options_run(ra, dec, 7), _options_run(ra, dec, 7), _options_run(ra, dec, 8)
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    assert len(a) != len(c) or not np.array_equal(a["tcb_jd"], c["tcb_jd"])


def test_results_do_not_depend_on_chunks_or_processes(monkeypatch):
    ra, dec = _random_sky(200, seed=4)
    one = _options_run(ra, dec, 7)
    # chunk = max(64, entries // (n_intervals + 1)) = 64 stars: several chunks inside each block
    monkeypatch.setattr(transits_module, "_F_ENTRIES_PER_CHUNK", 1)
    monkeypatch.setattr(transits_module, "_STARS_PER_BLOCK", 70)
    two = _options_run(ra, dec, 7, n_jobs=2)
    pd.testing.assert_frame_equal(one, two, check_exact=True)
    # Draws are keyed by source index: adding stars after the first 40 changes nothing for them.
    first = _options_run(ra[:40], dec[:40], 7)
    pd.testing.assert_frame_equal(first, one[one["source_index"] < 40].reset_index(drop=True), check_exact=True)


@pytest.mark.parametrize("kwargs", [
    dict(ra_deg=[0.0], dec_deg=[91.0]),
    dict(ra_deg=[0.0, 1.0], dec_deg=[0.0]),
    dict(ra_deg=[np.nan], dec_deg=[0.0]),
    dict(start="2016-01-01", end="2015-01-01"),
    dict(start="2010-01-01", end="2015-01-01"),
    dict(start="not a date"),
    dict(dilution=1.5),
    dict(dead_time_fraction=1.0),
    dict(law={"precession_S": 4.22}),
])
def test_bad_input_raises_user_input_error(kwargs):
    args = dict(ra_deg=[0.0], dec_deg=[0.0], start="2015-01-01", end="2015-02-01")
    args.update(kwargs)
    with pytest.raises(UserInputError):
        find_transits(args.pop("ra_deg"), args.pop("dec_deg"), args.pop("start"), args.pop("end"), **args)


def test_the_given_law_is_used():
    # A law with a 90 deg basic angle: the F transit trails the P transit by 90 deg / omega_z.
    law = ScanningLaw(name="test", basic_angle_deg=90.0)
    df = find_transits([157.5], [0.0], "2014-10-01", "2015-01-01", law=law)
    spans = df.groupby("group")["tcb_jd"].agg(["size", "min", "max"])
    lag_h = (spans["max"] - spans["min"])[spans["size"] == 2].to_numpy() * 24
    assert lag_h.size >= 2
    expected_h = 90 * 3600 / law.spin_rate_arcsec_s / 3600
    np.testing.assert_allclose(lag_h, expected_h, atol=FOV_LAG_TOLERANCE_S / 3600)
