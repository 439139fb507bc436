"""Density laws, luminosity functions, extinction and kinematics of the galaxy model."""

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import ICRS, SkyCoord

from mcsweep.population.galaxy import parameters as P
from mcsweep.population.galaxy.density import component_shape, heliocentric_to_galactocentric
from mcsweep.population.galaxy.extinction import DustModel
from mcsweep.population.galaxy.kinematics import AstrometryTransform, draw_velocities, mean_lag_kms
from mcsweep.population.galaxy.luminosity import (build_luminosity_table, imf, load_dwarf_sequence,
                                                  load_local_lf, turnoff_mass)

REL_TOL_LOCAL_LF = 1e-9      # relative: components must add up to the local LF exactly
EXTINCTION_REL_TOL = 0.01     # relative: trapezoid on the 0.05-mag distance grid
PM_TOL_MASYR = 1e-6           # mas/yr: our affine Galactocentric map vs astropy
POS_TOL_DEG = 1e-9            # deg


@pytest.mark.parametrize("comp", [c for c in P.COMPONENTS if c.law != "bulge"], ids=lambda c: c.name)
def test_shapes_are_one_at_the_sun_and_fall_off_vertically(comp):
    z_sun = P.Z_SUN_PC * 1e-3
    assert component_shape(comp, -P.R0_KPC, 0.0, z_sun) == pytest.approx(1.0, rel=1e-12)
    z = np.array([0.0, 0.2, 0.5, 1.0, 3.0])
    s = component_shape(comp, np.full(5, -P.R0_KPC), np.zeros(5), z)
    # strictly decreasing until the density underflows to 0 (the youngest giants' disc
    # is ~60 pc thick: exp(-(z/eps)^2) is below 1e-300 at 1 kpc)
    positive = s > 0
    assert positive[:3].all()
    assert np.all(np.diff(s[positive]) < 0) and np.all(s[~positive] == 0)


def test_bulge_peaks_at_centre_and_thick_disc_is_smooth_at_xl():
    assert component_shape(P.BULGE, 0.0, 0.0, 0.0) == pytest.approx(1.0)
    assert component_shape(P.BULGE, 5.0, 0.0, 0.0) < 1e-3
    # a bar: longer along its major axis (11 deg from the Sun-centre line) than across
    assert component_shape(P.BULGE, 1.5, 0.0, 0.0) > component_shape(P.BULGE, 0.0, 1.5, 0.0)
    xl = P.THICK_DISC_XL_KPC
    below = component_shape(P.THICK_DISC, -P.R0_KPC, 0.0, xl - 1e-9)
    above = component_shape(P.THICK_DISC, -P.R0_KPC, 0.0, xl + 1e-9)
    assert below == pytest.approx(above, rel=1e-6)


def test_discs_are_cut_beyond_14_kpc():
    for comp in (P.THIN_DISC[3], P.THICK_DISC):
        assert component_shape(comp, -P.DISC_CUTOFF_KPC - 0.1, 0.0, 0.0) == 0.0


def test_heliocentric_geometry():
    x, y, z = heliocentric_to_galactocentric(0.0, 0.0, P.R0_KPC)
    assert (x, y) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert z == pytest.approx(P.Z_SUN_PC * 1e-3)


def test_imf_is_continuous_and_normalised():
    pieces = P.THIN_DISC[2].imf
    assert imf(np.array([1.0]), pieces)[0] == pytest.approx(1.0)
    lo, hi = imf(np.array([1 - 1e-9, 1 + 1e-9]), pieces)
    assert lo == pytest.approx(hi, rel=1e-6)
    assert imf(np.array([0.5]), pieces)[0] == pytest.approx(0.5 ** -1.6)


def test_local_components_add_up_to_the_local_luminosity_function():
    local = [c for c in P.COMPONENTS if c.law != "bulge"]
    table = build_luminosity_table(local)
    mv, phi = load_local_lf()
    seq_mv, _, seq_m = load_dwarf_sequence()
    summed = table.cdf.sum(axis=0)
    # dwarfs M_V >= 4.5: Wielen/Allen (faint_scale = 1); M_V < 4.5: Bovy (2017)
    # dn/dM = 0.016 M^-4.7 pc^-3 Msun^-1 integrated in closed form over each bin's
    # masses (Mamajek sequence); giants: Bovy's 3.9e-4 pc^-3
    faint = phi[mv > 4.4].sum()
    bright_mv = mv[(mv > P.GIANT_MV_MAX) & (mv < 4.4)]
    m_of = lambda x: 10 ** np.interp(x, seq_mv, np.log10(seq_m))  # noqa: E731
    bright = (0.016 / 3.7 * (m_of(bright_mv + 0.5) ** -3.7 - m_of(bright_mv - 0.5) ** -3.7)).sum()
    assert summed[-1] == pytest.approx(faint + bright + 3.9e-4, rel=REL_TOL_LOCAL_LF)
    # giants (M_V <= 1, M_G = M_V - 0.31) are not shifted: exact up to M_G = 1.2
    i = np.searchsorted(table.mg, P.GIANT_MV_MAX + 0.5 + P.GIANT_G_MINUS_V + 1e-9)
    assert summed[i] == pytest.approx(3.9e-4, rel=REL_TOL_LOCAL_LF)
    # each age bin's giants sit in its giant-only companion, none in the dwarf component
    k = table.names.index("thin_disc_3")
    assert table.cdf[k, i] == 0.0
    assert table.cdf[table.names.index("thin_disc_3_giants"), -1] > 0


def test_old_populations_have_no_bright_dwarfs():
    table = build_luminosity_table(P.COMPONENTS)
    dens = table.density()
    mg = table.mg[:-1] + 0.025
    k = table.names.index("halo")
    # between the giants (M_G <= 1.2) and the metal-poor turn-off (M_V = 4) nothing
    sel = (mg > 1.5) & (mg < P.OLD_METAL_POOR_TURNOFF_MV - 0.6)
    assert np.all(dens[k, sel] == 0.0)
    assert dens[k, (mg > 4.5) & (mg < 6)].min() > 0
    assert turnoff_mass(10.0) == pytest.approx(1.0)


def test_extinction_towards_the_pole_and_the_anticentre():
    dust = DustModel()
    d = 10.0 ** (0.2 * np.arange(-3.0, 19.5, 0.05) - 2.0)   # kpc, the model's grid
    x, y, z = heliocentric_to_galactocentric(0.0, 90.0, d)
    a_pole = dust.a_g(x, y, z, d)[-1]
    h = dust.h_z
    expect = dust.ag_over_av * dust.av_per_kpc * h * np.exp(-(P.Z_SUN_PC * 1e-3 - dust.z_dust) / h)
    assert a_pole == pytest.approx(expect, rel=EXTINCTION_REL_TOL)
    x, y, z = heliocentric_to_galactocentric(180.0, 0.0, d)
    a = dust.a_g(x, y, z, d)
    off = np.exp(-(P.Z_SUN_PC * 1e-3 - dust.z_dust) / h)
    expect = dust.ag_over_av * dust.av_per_kpc * dust.h_r * (1 - np.exp(-d / dust.h_r)) * off
    i = np.searchsorted(d, 2.0)
    assert a[i] == pytest.approx(expect[i], rel=EXTINCTION_REL_TOL)
    assert np.all(DustModel(av_per_kpc=0.0).a_g(x, y, z, d) == 0.0)


def test_astrometry_matches_astropy_galactocentric(rng):
    tr = AstrometryTransform(r0_kpc=8.5, z_sun_pc=15.0, v_sun_kms=(11.1, 238.24, 7.25))
    n = 200
    l, b = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))
    d = rng.uniform(0.01, 20.0, n)
    pos = tr.galactocentric_position(l, b, d)
    v = rng.normal(0, 150, (3, n))
    ra, dec, pmra, pmdec = tr.astrometry(l, b, d, v)
    gc = SkyCoord(x=pos[0] * u.kpc, y=pos[1] * u.kpc, z=pos[2] * u.kpc,
                  v_x=v[0] * u.km / u.s, v_y=v[1] * u.km / u.s, v_z=v[2] * u.km / u.s,
                  frame=tr.frame)
    ic = gc.transform_to(ICRS())
    gal = SkyCoord(l=l * u.deg, b=b * u.deg, frame="galactic").icrs
    assert np.allclose(ra, gal.ra.deg, atol=POS_TOL_DEG) and np.allclose(dec, gal.dec.deg, atol=POS_TOL_DEG)
    assert np.allclose(ic.distance.to_value(u.kpc), d, rtol=1e-9)
    assert np.allclose(pmra, ic.pm_ra_cosdec.to_value(u.mas / u.yr), atol=PM_TOL_MASYR)
    assert np.allclose(pmdec, ic.pm_dec.to_value(u.mas / u.yr), atol=PM_TOL_MASYR)


def test_star_moving_with_the_sun_has_no_proper_motion():
    v_sun = (11.1, 238.24, 7.25)
    tr = AstrometryTransform(r0_kpc=8.5, z_sun_pc=15.0, v_sun_kms=v_sun)
    _, _, pmra, pmdec = tr.astrometry(np.array([30.0]), np.array([10.0]), np.array([1.0]),
                                      np.array(v_sun)[:, None])
    assert abs(pmra[0]) < PM_TOL_MASYR and abs(pmdec[0]) < PM_TOL_MASYR


def test_rotation_direction_and_lags():
    v = draw_velocities(np.array([-8.5]), np.array([0.0]), np.array([0.0]),
                        np.zeros((1, 3)), np.zeros((3, 1)), v_circ_kms=226.0)
    assert v[:, 0] == pytest.approx([0.0, 226.0, 0.0])
    assert mean_lag_kms(P.HALO, v_circ_kms=200.0) == 200.0
    assert mean_lag_kms(P.THICK_DISC) == 46.0
    lags = [mean_lag_kms(c) for c in P.THIN_DISC]
    assert all(0 < x < 15 for x in lags)   # Jeans drift of the thin disc: a few km/s
    assert lags[-1] > lags[1]               # hotter populations lag more


def test_giant_kinematics_follow_their_thinner_discs():
    # isothermal disc (Spitzer 1942): thickness ~ sigma_W^2 at a given surface density, so
    # a disc GIANT_THICKNESS_FACTOR as thick has sigma_W^2 smaller by the same factor
    # (closed form); the ellipsoid keeps each age bin's shape (R03 Table 2)
    for dwarf, giant in zip(P.thin_disc(), P.THIN_DISC_GIANTS):
        assert giant.eps / dwarf.eps == pytest.approx(P.GIANT_THICKNESS_FACTOR, rel=1e-12)
        assert (giant.sigma_uvw[2] / dwarf.sigma_uvw[2]) ** 2 == pytest.approx(
            giant.eps / dwarf.eps, rel=1e-12)
        assert np.divide(giant.sigma_uvw, giant.sigma_uvw[2]) == pytest.approx(
            np.divide(dwarf.sigma_uvw, dwarf.sigma_uvw[2]), rel=1e-12)
        # colder populations lag less (Jeans asymmetric drift)
        assert 0 < mean_lag_kms(giant) < mean_lag_kms(dwarf)
