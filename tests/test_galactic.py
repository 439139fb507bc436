"""Fast ICRS -> galactic conversion against astropy's SkyCoord."""

import numpy as np
from astropy import units as u
from astropy.coordinates import SkyCoord

from mcsweep.galactic import galactic_from_icrs, icrs_to_galactic_matrix

#: Agreement with SkyCoord(...).galactic: both apply the same rotation; rounding only.
FRAME_TOL_MAS = 1e-5  # mas
#: A rotation built from astropy's chained matrices: orthonormal to a few ulp.
ORTHO_TOL = 1e-14


def test_matrix_is_a_rotation():
    m = icrs_to_galactic_matrix()
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=ORTHO_TOL)
    assert abs(np.linalg.det(m) - 1) < ORTHO_TOL


def test_agrees_with_skycoord_over_the_sky():
    rng = np.random.default_rng(15)
    ra = rng.uniform(0, 360, 20000)
    dec = np.degrees(np.arcsin(rng.uniform(-1, 1, 20000)))
    ra = np.concatenate([ra, [0.0, 266.40499, 192.85948]])  # include the galactic centre and north pole
    dec = np.concatenate([dec, [90.0, -28.93617, 27.12825]])
    l_deg, b_deg = galactic_from_icrs(ra, dec)
    ref = SkyCoord(ra=ra * u.deg, dec=dec * u.deg, frame="icrs").galactic
    sep = SkyCoord(l=l_deg * u.deg, b=b_deg * u.deg, frame="galactic").separation(ref)
    assert sep.to_value(u.mas).max() < FRAME_TOL_MAS
    assert np.all((l_deg >= 0) & (l_deg < 360))


def test_broadcasts():
    l_deg, b_deg = galactic_from_icrs(np.zeros((3, 1)), np.linspace(-60, 60, 4))
    assert l_deg.shape == b_deg.shape == (3, 4)


#: Proper motions rotated between the frames: rounding of a few mas/yr-sized vectors.
PM_TOL_MASYR = 1e-9


def test_proper_motion_rotation_agrees_with_skycoord():
    from mcsweep.galactic import pm_galactic_from_icrs, pm_icrs_from_galactic

    rng = np.random.default_rng(16)
    n = 5000
    ra, dec = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))
    pmra, pmdec = rng.normal(0, 30, n), rng.normal(0, 30, n)
    ref = SkyCoord(ra=ra * u.deg, dec=dec * u.deg, pm_ra_cosdec=pmra * u.mas / u.yr,
                   pm_dec=pmdec * u.mas / u.yr, frame="icrs").galactic
    pml, pmb = pm_galactic_from_icrs(ra, dec, pmra, pmdec)
    assert np.abs(pml - ref.pm_l_cosb.to_value(u.mas / u.yr)).max() < PM_TOL_MASYR
    assert np.abs(pmb - ref.pm_b.to_value(u.mas / u.yr)).max() < PM_TOL_MASYR
    back_ra, back_dec = pm_icrs_from_galactic(ref.l.deg, ref.b.deg, pml, pmb)
    assert np.abs(back_ra - pmra).max() < PM_TOL_MASYR and np.abs(back_dec - pmdec).max() < PM_TOL_MASYR
