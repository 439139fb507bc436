"""Eq. 1 design matrix against astropy's own geometry, plus epochs and masking."""

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import (
    CartesianRepresentation,
    SkyCoord,
    get_body_barycentric,
    solar_system_ephemeris,
)
from astropy.time import Time

from mcsweep.astrometry.design import (
    JULIAN_YEAR_DAYS,
    design_matrix,
    reference_epoch,
    tangent_triad,
    years_since,
)

#: Agreement required between our Eq. 1 displacements and astropy's (1 microarcsec).
ASTROPY_TOLERANCE_MAS = 1e-3  # 1 microarcsec
#: Rows computed from differently shaped or masked inputs: numpy may take vector or
#: scalar loops for different elements, which can differ in the last bits.
RTOL_PATHS = 1e-13

#: Gaia at L2: 1.01 x the Sun-EMB vector from the Sun (docs/architecture.md), computed
#: here directly from astropy, independently of mcsweep.scanning.ephemeris.
L2_FACTOR = 1.01


def _observer_au(tcb_jd):
    t = Time(tcb_jd, format="jd", scale="tcb")
    with solar_system_ephemeris.set("builtin"):
        sun = get_body_barycentric("sun", t).xyz.to_value(u.au)
        emb = get_body_barycentric("earth-moon-barycenter", t).xyz.to_value(u.au)
    return (sun + L2_FACTOR * (emb - sun)).T  # (k, 3)


def _al_ac_offsets_mas(ref: SkyCoord, seen: SkyCoord, psi_deg):
    """AL/AC components of the offset ref -> seen from astropy's separation and PA.

    An offset of size s at position angle PA (east of north) has components
    (s sin PA, s cos PA) in (east, north); projected on AL = (sin psi, cos psi) and
    AC = (-cos psi, sin psi) that is s cos(PA - psi) and s sin(psi - PA).
    """
    sep = ref.separation(seen).to_value(u.mas)
    pa = ref.position_angle(seen).to_value(u.rad)
    psi = np.radians(psi_deg)
    return sep * np.cos(pa - psi), sep * np.sin(psi - pa)


def _model_rows(ra, dec, t_yr, psi, obs):
    """AL rows then AC rows for one star with unit sigmas (rows in mas per parameter)."""
    A = design_matrix(np.array([ra]), np.array([dec]), t_yr[None], psi[None], obs[None],
                      sigma_al_mas=1.0, sigma_ac_mas=1.0)
    k = len(t_yr)
    return A[0, :k], A[0, k:]


@pytest.mark.parametrize("ra_deg, dec_deg", [(157.5, 0.0), (10.0, 62.0), (266.4, -28.9), (300.0, -85.0)])
def test_parallax_displacement_matches_astropy(table1, ra_deg, dec_deg):
    """Star at 1 kpc versus the same star at infinity, seen from Gaia (Eq. 1's parallax column)."""
    tcb_jd, psi = table1["tcb_jd"], table1["psi_deg"]
    obs = _observer_au(tcb_jd)
    star = SkyCoord(ra_deg * u.deg, dec_deg * u.deg, distance=1 * u.kpc, frame="icrs")
    star_au = star.cartesian.xyz.to_value(u.au)
    seen = SkyCoord(CartesianRepresentation((star_au[None, :] - obs).T * u.au), frame="icrs")
    at_infinity = SkyCoord(ra_deg * u.deg, dec_deg * u.deg, frame="icrs")
    al_ref, ac_ref = _al_ac_offsets_mas(at_infinity, seen, psi)

    al_rows, ac_rows = _model_rows(ra_deg, dec_deg, np.zeros_like(psi), psi, obs)
    parallax_mas = 1.0  # 1 kpc
    np.testing.assert_allclose(al_rows[:, 2] * parallax_mas, al_ref, rtol=0, atol=ASTROPY_TOLERANCE_MAS)
    np.testing.assert_allclose(ac_rows[:, 2] * parallax_mas, ac_ref, rtol=0, atol=ASTROPY_TOLERANCE_MAS)
    # The test must be able to fail: the displacements are of order 1 mas.
    assert np.max(np.hypot(al_ref, ac_ref)) > 0.5


def test_full_five_parameter_motion_matches_astropy(table1):
    """Position offset + proper motion + parallax versus astropy's space motion."""
    ra, dec = 40.0, 25.0
    tcb_jd, psi = table1["tcb_jd"], table1["psi_deg"]
    obs = _observer_au(tcb_jd)
    ep = reference_epoch(tcb_jd[None])
    t_yr = years_since(tcb_jd[None], ep)[0]
    plx_mas, pmra, pmdec = 2.5, 37.0, -21.0
    star = SkyCoord(ra * u.deg, dec * u.deg, distance=(1000.0 / plx_mas) * u.pc,
                    pm_ra_cosdec=pmra * u.mas / u.yr, pm_dec=pmdec * u.mas / u.yr,
                    radial_velocity=0 * u.km / u.s, frame="icrs",
                    obstime=Time(ep[0], format="jd", scale="tcb"))
    moved = star.apply_space_motion(new_obstime=Time(tcb_jd, format="jd", scale="tcb"))
    bary_au = moved.cartesian.xyz.to_value(u.au).T  # (k, 3)
    seen = SkyCoord(CartesianRepresentation((bary_au - obs).T * u.au), frame="icrs")
    reference = SkyCoord(ra * u.deg, dec * u.deg, frame="icrs")
    al_ref, ac_ref = _al_ac_offsets_mas(reference, seen, psi)

    al_rows, ac_rows = _model_rows(ra, dec, t_yr, psi, obs)
    x_true = np.array([0.0, 0.0, plx_mas, pmra, pmdec])
    np.testing.assert_allclose(al_rows @ x_true, al_ref, rtol=0, atol=ASTROPY_TOLERANCE_MAS)
    np.testing.assert_allclose(ac_rows @ x_true, ac_ref, rtol=0, atol=ASTROPY_TOLERANCE_MAS)
    assert np.max(np.abs(al_ref)) > 10.0  # proper motion over ~0.6 yr dominates


def test_position_columns_follow_scan_direction():
    """A pure offset to the east/north projects as (sin psi, cos psi) on AL (Table 1)."""
    psi = np.array([[0.0, 90.0, 180.0, 270.0]])
    zeros = np.zeros_like(psi)
    A = design_matrix(np.array([0.0]), np.array([0.0]), zeros, psi, np.zeros((1, 4, 3)),
                      sigma_al_mas=1.0, sigma_ac_mas=1.0)
    # psi = 0: the FoV moves north, so a northward offset is purely AL.
    np.testing.assert_allclose(A[0, :4, :2], [[0, 1], [1, 0], [0, -1], [-1, 0]], atol=1e-15)
    np.testing.assert_allclose(A[0, 4:, :2], [[-1, 0], [0, 1], [1, 0], [0, -1]], atol=1e-15)


def test_tangent_triad_is_orthonormal_and_points_east_north():
    p, q, r = tangent_triad([0.0, 123.0, 300.0], [0.0, 45.0, -80.0])
    for a in (p, q, r):
        np.testing.assert_allclose(np.linalg.norm(a, axis=-1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(np.einsum("ni,ni->n", p, q), 0.0, atol=1e-15)
    np.testing.assert_allclose(np.cross(p, q), r, atol=1e-15)  # right-handed (east, north, out)
    np.testing.assert_allclose(q[:, 2] >= 0, True)  # north has a positive z component


def test_rows_are_divided_by_sigma(table1):
    tcb_jd, psi = table1["tcb_jd"], table1["psi_deg"]
    k = len(psi)
    obs = _observer_au(tcb_jd)
    t_yr = years_since(tcb_jd[None], reference_epoch(tcb_jd[None]))
    args = (np.array([157.5]), np.array([0.0]), t_yr, psi[None], obs[None])
    unit = design_matrix(*args, sigma_al_mas=1.0, sigma_ac_mas=1.0)
    sig_al = np.linspace(0.05, 0.5, k)[None]
    sig_ac = 7.0 * sig_al
    scaled = design_matrix(*args, sigma_al_mas=sig_al, sigma_ac_mas=sig_ac)
    np.testing.assert_allclose(scaled[0, :k], unit[0, :k] / sig_al[0, :, None], rtol=1e-15)
    np.testing.assert_allclose(scaled[0, k:], unit[0, k:] / sig_ac[0, :, None], rtol=1e-15)
    al_only = design_matrix(*args, sigma_al_mas=sig_al)
    assert al_only.shape == (1, k, 5)
    np.testing.assert_allclose(al_only, scaled[:, :k], rtol=RTOL_PATHS, atol=0)


def test_absent_transits_give_zero_rows_and_may_hold_nan():
    rng = np.random.default_rng(11)
    n, k = 6, 5
    t = rng.uniform(-1, 1, (n, k))
    psi = rng.uniform(0, 360, (n, k))
    obs = rng.normal(size=(n, k, 3))
    mask = rng.uniform(size=(n, k)) < 0.6
    t_nan, psi_nan, obs_nan = t.copy(), psi.copy(), obs.copy()
    t_nan[~mask] = np.nan
    psi_nan[~mask] = np.nan
    obs_nan[~mask] = np.nan
    ra, dec = rng.uniform(0, 360, n), rng.uniform(-80, 80, n)
    A = design_matrix(ra, dec, t_nan, psi_nan, obs_nan, sigma_al_mas=0.2, sigma_ac_mas=1.0, mask=mask)
    full = design_matrix(ra, dec, t, psi, obs, sigma_al_mas=0.2, sigma_ac_mas=1.0)
    rows = np.concatenate([mask, mask], axis=1)
    assert np.all(np.isfinite(A))
    np.testing.assert_array_equal(A[~rows], 0.0)
    np.testing.assert_allclose(A[rows], full[rows], rtol=RTOL_PATHS, atol=0)


def test_reference_epoch_is_mean_of_present_epochs():
    jd = np.array([[2457000.1, 2457100.7, 2457400.2], [2457010.0, np.nan, 2457020.0], [np.nan] * 3])
    mask = np.array([[True, True, True], [True, False, True], [False, False, False]])
    ep = reference_epoch(jd, mask)
    # Means computed by hand (relative to 2457000 to keep the digits visible).
    np.testing.assert_allclose(ep[:2] - 2457000.0, [(0.1 + 100.7 + 400.2) / 3, 15.0], rtol=0, atol=1e-8)
    assert np.isnan(ep[2])
    # astropy's year is the Julian year (IAU): an independent value of the constant.
    julian_year_d = (1 * u.yr).to_value(u.day)
    np.testing.assert_allclose(years_since(jd[:1], ep[:1]), (jd[:1] - ep[0]) / julian_year_d, rtol=1e-15)
    assert JULIAN_YEAR_DAYS == julian_year_d


@pytest.mark.parametrize("kwargs, match", [
    (dict(sigma_al_mas=0.0), "sigma_al_mas"),
    (dict(sigma_al_mas=0.1, sigma_ac_mas=-1.0), "sigma_ac_mas"),
])
def test_rejects_non_positive_sigma(kwargs, match):
    with pytest.raises(ValueError, match=match):
        design_matrix(np.zeros(1), np.zeros(1), np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2, 3)),
                      **kwargs)


def test_rejects_inconsistent_shapes():
    with pytest.raises(ValueError, match="obs_au"):
        design_matrix(np.zeros(2), np.zeros(2), np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)),
                      sigma_al_mas=1.0)
