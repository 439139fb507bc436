"""Attitude of the nominal scanning law: closed-form geometry and the NSL equations.

On one NSL segment over 2014-2020 (the flown law's 2014-09-25 - 2017-01-27 segment,
extended): the segmented flown law is checked per segment in test_segments.py.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mcsweep.scanning import ScanningLaw
from mcsweep.scanning.attitude import attitude_for
from mcsweep.scanning.sun import nominal_sun_longitude

SOLAR_ASPECT_TOLERANCE_RAD = 1e-9  # rad, Sun - spin axis angle vs the law's solar aspect angle xi
ORTHONORMAL_TOLERANCE = 1e-13  # dimensionless
REFERENCE_PHASE_TOLERANCE_RAD = 1e-10  # rad
NSL_RATE_RTOL = 1e-6  # relative, finite differences of the interpolated angles
SPIN_RATE_RTOL = 1e-6  # relative, inertial spin rate from finite differences of A(t)
INTERPOLATION_TOLERANCE_RAD = 1e-8  # rad, table interpolation vs an independent integration
PRECESSION_PERIOD_DAYS = (62.0, 64.0)  # "about 63 days" (S = 4.22)


@pytest.fixture(scope="module")
def law():
    # The flown law's 2014-09-25 - 2017-01-27 segment as a one-segment law (mcsweep's
    # flown law before the law became segments, scanning-law-history.md).
    return ScanningLaw(name="one_segment", segments=(), ref_epoch_tcb="2015-01-01T00:00:00",
                       nu_ref_deg=323.3708, omega_ref_deg=95.1324)


@pytest.fixture(scope="module")
def att(law):
    return attitude_for(law)


@pytest.fixture(scope="module")
def times():
    rng = np.random.default_rng(11)
    return np.sort(rng.uniform(2456900.5, 2458900.5, 400))  # 2014-09 .. 2020-02 (TCB JD)


def test_spin_axis_is_45_deg_from_the_nominal_sun(att, law, times):
    z = att.spin_axis(times)
    lon, _ = nominal_sun_longitude(times)
    sun = np.stack([np.cos(lon), np.sin(lon), np.zeros_like(lon)], axis=-1)
    angle = np.arccos(np.clip(np.sum(z * sun, axis=-1), -1, 1))
    assert np.max(np.abs(angle - math.radians(law.solar_aspect_deg))) < SOLAR_ASPECT_TOLERANCE_RAD


def test_attitude_matrix_is_a_rotation_with_the_documented_spin_axis(att, law, times):
    a = att.matrix(times)
    np.testing.assert_allclose(np.einsum("tji,tjk->tik", a, a), np.broadcast_to(np.eye(3), a.shape),
                               atol=ORTHONORMAL_TOLERANCE)
    np.testing.assert_allclose(np.linalg.det(a), 1.0, atol=ORTHONORMAL_TOLERANCE)
    # Spin axis in the Sun-centred frame is (cos xi, sin xi cos nu, sin xi sin nu).
    lam, _, nu, _, _, _ = att.heliotropic(times)
    z = a[:, :, 2]
    c, s = np.cos(lam), np.sin(lam)
    z_sun = np.stack([c * z[:, 0] + s * z[:, 1], -s * z[:, 0] + c * z[:, 1], z[:, 2]], axis=-1)
    xi = math.radians(law.solar_aspect_deg)
    expected = np.stack([np.full_like(nu, math.cos(xi)), math.sin(xi) * np.cos(nu),
                         math.sin(xi) * np.sin(nu)], -1)
    np.testing.assert_allclose(z_sun, expected, atol=ORTHONORMAL_TOLERANCE)
    np.testing.assert_allclose(att.spin_axis(times), z, atol=ORTHONORMAL_TOLERANCE)


def test_phases_at_the_reference_epoch(att, law):
    _, _, nu, _, omega, _ = att.heliotropic(np.array([law.ref_epoch_jd]))
    assert abs(nu[0] - math.radians(law.nu_ref_deg)) < REFERENCE_PHASE_TOLERANCE_RAD
    assert abs(omega[0] - math.radians(law.omega_ref_deg)) < REFERENCE_PHASE_TOLERANCE_RAD


def test_interpolated_angles_obey_the_nsl_equations(att, law, times):
    h = 0.01  # day
    t_p, t_m = times + h, times - h
    _, _, nu_p, _, om_p, _ = att.heliotropic(t_p)
    _, _, nu_m, _, om_m, _ = att.heliotropic(t_m)
    nu_dot_fd = (nu_p - nu_m) / (t_p - t_m)
    om_dot_fd = (om_p - om_m) / (t_p - t_m)
    lam, lam_dot, nu, _, _, _ = att.heliotropic(times)
    xi = math.radians(law.solar_aspect_deg)
    s = law.precession_S
    nu_dot = lam_dot * (np.sqrt(s**2 - np.cos(nu) ** 2) + math.cos(xi) * np.sin(nu)) / math.sin(xi)
    om_dot = law.spin_rate_rad_day - math.cos(xi) * nu_dot - math.sin(xi) * np.sin(nu) * lam_dot
    np.testing.assert_allclose(nu_dot_fd, nu_dot, rtol=NSL_RATE_RTOL)
    np.testing.assert_allclose(om_dot_fd, om_dot, rtol=NSL_RATE_RTOL)


def test_inertial_spin_rate_about_the_spin_axis_is_omega_z(att, law, times):
    # Angular velocity in the SRS from A^T dA/dt (skew-symmetric); its z component is the
    # quantity the NSL keeps constant.
    h = 1e-5  # day (0.86 s)
    t_p, t_m = times + h, times - h
    a_dot = (att.matrix(t_p) - att.matrix(t_m)) / (t_p - t_m)[:, None, None]
    w = np.einsum("tji,tjk->tik", att.matrix(times), a_dot)
    np.testing.assert_allclose(w[:, 1, 0], law.spin_rate_rad_day, rtol=SPIN_RATE_RTOL)


def test_mean_precession_period_is_about_63_days(att):
    t0, t1 = 2457023.5, 2457023.5 + 5 * 365.25
    _, _, nu, _, _, _ = att.heliotropic(np.array([t0, t1]))
    period = (t1 - t0) * 2 * math.pi / (nu[1] - nu[0])
    assert PRECESSION_PERIOD_DAYS[0] < period < PRECESSION_PERIOD_DAYS[1]


def test_table_interpolation_matches_an_independent_integration(att, law):
    # Integrate nu once more, from the reference epoch straight to a few distant epochs.
    xi = math.radians(law.solar_aspect_deg)

    def rhs(t, y):
        _, lam_dot = nominal_sun_longitude(t)
        return [lam_dot * (math.sqrt(law.precession_S**2 - math.cos(y[0]) ** 2)
                           + math.cos(xi) * math.sin(y[0])) / math.sin(xi)]

    targets = law.ref_epoch_jd + np.array([-400.123, 17.77, 913.3, 1800.05])
    for t in targets:
        sol = solve_ivp(rhs, (law.ref_epoch_jd, t), [math.radians(law.nu_ref_deg)], method="LSODA",
                        rtol=1e-12, atol=1e-12)
        _, _, nu, _, _, _ = att.heliotropic(np.array([t]))
        assert abs(sol.y[0, -1] - nu[0]) < INTERPOLATION_TOLERANCE_RAD


def test_nominal_preset_differs_only_in_design_constants():
    flown, nominal = ScanningLaw.preset("flown"), ScanningLaw.preset("nominal")
    assert (nominal.precession_S, nominal.spin_rate_arcsec_s) == (4.22, 60.0)
    # 60 arcsec/s is a 6 h spin period; the flown rate takes 14.2 s longer per turn.
    assert nominal.spin_period_days * 24 == pytest.approx(6.0, abs=1e-12)
    assert (flown.spin_period_days - nominal.spin_period_days) * 86400 == pytest.approx(14.2, abs=0.1)
