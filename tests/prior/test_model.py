"""mcsweep.prior.Prior against closed-form evaluations of Eqs. 14-18 and a run's files."""

import json

import numpy as np
import pandas as pd
import pytest
from astropy import units as u
from astropy.coordinates import FK5, ICRS, Galactic, SkyCoord

from mcsweep.astrometry.solve import prior_diagonal
from mcsweep.errors import UserInputError
from mcsweep.prior import Prior, sigma_f90
from mcsweep.experiments.f90_sweep.fit import coefficient_table

#: Hand evaluations keep 6-7 significant digits in log10 sigma.
HAND_RTOL = 1e-6
#: The same sky direction given in different frames: astropy's transformations agree to
#: ~1e-12 deg, and d log10(sigma) / d(angle) < 0.02 per degree, so 1e-10 is generous.
FRAME_RTOL = 1e-10
#: Same formula through different code paths (array vs scalar numpy kernels).
RTOL_PATHS = 1e-13


def paper_closed_form(l_deg, b_deg, g):
    """Eqs. 14-17 typed out from the paper, independent of the package's tables."""
    s0 = 2.187 - 0.2547 * g + 0.006382 * g**2
    s1 = 0.114 - 0.0579 * g + 0.01369 * g**2 - 0.000506 * g**3
    s2 = 0.031 - 0.0062 * g
    lr, br = np.radians(l_deg), np.radians(b_deg)
    return 10 ** (s0 + s1 * np.abs(np.sin(br)) + s2 * np.cos(br) * np.cos(lr))


@pytest.fixture(scope="module")
def paper():
    return Prior.paper()


def test_hand_points_with_skycoord_and_lb(paper):
    # Table 1 direction, G = 15: s0 = -0.19755, s1 = 0.618, s2 = -0.062 (hand, tests/prior/test_formula.py)
    log_s = -0.19755 + 0.618 * np.sin(np.radians(46.5)) - 0.062 * np.cos(np.radians(46.5)) * np.cos(np.radians(245.7))
    c = SkyCoord(l=245.7 * u.deg, b=46.5 * u.deg, frame="galactic")
    plx = paper.sigma_parallax(c, G=15.0)
    assert plx.unit == u.mas and plx.value == pytest.approx(10**log_s, rel=HAND_RTOL)
    assert paper.sigma_parallax(c, 15.0).value == pytest.approx(10**log_s, rel=HAND_RTOL)
    assert paper.sigma_parallax(245.7, 46.5, 15.0).value == pytest.approx(10**log_s, rel=HAND_RTOL)
    pm = paper.sigma_pm(245.7 * u.deg, 46.5 * u.deg, G=15.0 * u.mag)
    assert pm.unit == u.mas / u.yr and pm.value == pytest.approx(10 * 10**log_s, rel=HAND_RTOL)
    # G = 10, l = 90, b = -30: log10 sigma = 0.2782 + 0.398 * 0.5 = 0.4772
    assert paper.sigma_parallax(90.0, -30.0, G=10.0).value == pytest.approx(10**0.4772, rel=HAND_RTOL)


def test_faint_and_bright_rules_apply_to_both_kinds(paper):
    # G > 20: the G = 20 value (Sect. 3.4); at b = 90: log10 sigma = -0.3542 + 0.384 = 0.0298
    for g in (20.0, 20.5, 23.0):
        assert paper.sigma_parallax(180.0, 90.0, G=g).value == pytest.approx(10**0.0298, rel=HAND_RTOL)
        assert paper.sigma_pm(180.0, 90.0, G=g).value == pytest.approx(10 * 10**0.0298, rel=HAND_RTOL)
    # G < 6: extrapolated polynomials (default) or the G = 6 value (clamp).
    assert paper.sigma_parallax(0.0, 0.0, G=3.0).value == pytest.approx(10**1.492738, rel=HAND_RTOL)
    assert paper.sigma_pm(0.0, 0.0, G=3.0).value == pytest.approx(10 * 10**1.492738, rel=HAND_RTOL)
    clamp = Prior.paper(bright="clamp")
    assert clamp.sigma_parallax(0.0, 0.0, G=3.0).value == pytest.approx(10**0.882352, rel=HAND_RTOL)
    assert clamp.sigma_pm(0.0, 0.0, G=3.0).value == pytest.approx(10 * 10**0.882352, rel=HAND_RTOL)
    with pytest.raises(UserInputError, match="bright"):
        Prior.paper(bright="tycho")


def test_matches_closed_form_on_a_grid(paper):
    l_deg = np.linspace(0, 350, 36)[:, None, None]
    b_deg = np.linspace(-90, 90, 19)[None, :, None]
    g = np.linspace(6, 20, 15)[None, None, :]
    got = paper.sigma_parallax(l_deg, b_deg, G=g)
    assert got.shape == (36, 19, 15)
    np.testing.assert_allclose(got.to_value(u.mas), paper_closed_form(l_deg, b_deg, g), rtol=HAND_RTOL * 1e-3)


def test_frame_invariance(paper):
    rng = np.random.default_rng(5)
    ra = rng.uniform(0, 360, 500) * u.deg
    dec = np.degrees(np.arcsin(rng.uniform(-1, 1, 500))) * u.deg
    g = rng.uniform(5, 21, 500)
    icrs = SkyCoord(ra=ra, dec=dec, frame=ICRS())
    ref = paper.sigma_parallax(icrs, G=g)
    for other in (icrs.galactic, icrs.transform_to(FK5(equinox="J2000")), icrs.frame,
                  icrs.transform_to(Galactic()).frame):
        np.testing.assert_allclose(paper.sigma_parallax(other, G=g), ref, rtol=FRAME_RTOL, atol=0)
    gal = icrs.galactic
    np.testing.assert_allclose(paper.sigma_parallax(gal.l.deg, gal.b.deg, G=g), ref, rtol=FRAME_RTOL, atol=0)


def test_broadcasting_shapes(paper):
    c = SkyCoord(ra=np.linspace(0, 300, 3)[:, None] * u.deg, dec=np.zeros((3, 1)) * u.deg)
    g = np.array([8.0, 12.0, 16.0, 22.0])
    out = paper.sigma_parallax(c, G=g)
    assert out.shape == (3, 4)
    assert np.ndim(paper.sigma_parallax(10.0, 20.0, G=15.0)) == 0
    for i in range(3):
        for j in range(4):
            assert out[i, j].value == pytest.approx(paper.sigma_parallax(c[i, 0], G=g[j]).value, rel=RTOL_PATHS)
    np.testing.assert_array_equal(sigma_f90(245.7, 46.5, g), paper.sigma_parallax(245.7, 46.5, G=g).value)


def test_normal_matrix_is_eq18(paper):
    l_deg, b_deg, g = np.array([0.0, 100.0, 250.0]), np.array([-70.0, 5.0, 46.5]), np.array([7.0, 15.0, 21.0])
    sig = paper_closed_form(l_deg, b_deg, np.minimum(g, 20.0))
    for k in (1.0, 10.0):
        n_p = paper.normal_matrix(l_deg, b_deg, G=g, factor=k)
        assert n_p.shape == (3, 5, 5)
        np.testing.assert_allclose(np.diagonal(n_p, axis1=-2, axis2=-1), prior_diagonal(k * sig, 10.0),
                                   rtol=HAND_RTOL * 1e-3)
        off = n_p - np.einsum("...i,ij->...ij", np.diagonal(n_p, axis1=-2, axis2=-1), np.eye(5))
        assert not off.any()
    assert paper.normal_matrix(np.zeros((2, 3)), 10.0, G=15.0).shape == (2, 3, 5, 5)
    with pytest.raises(UserInputError, match="factor"):
        paper.normal_matrix(0.0, 0.0, G=15.0, factor=-1.0)


def test_bad_arguments(paper):
    with pytest.raises(TypeError, match="expected"):
        paper.sigma_parallax(10.0, G=15.0)
    with pytest.raises(UserInputError, match="angle"):
        paper.sigma_parallax(10.0 * u.mas / u.yr, 5.0 * u.deg, G=15.0)
    with pytest.raises(UserInputError, match="magnitudes"):
        paper.sigma_parallax(10.0, 5.0, G=15.0 * u.Jy)
    with pytest.raises(UserInputError, match="NaN"):
        paper.sigma_parallax(10.0, 5.0, G=np.nan)


def _write_run(run_dir, fitted, edges, confidence=0.8, ratio_R=5.0, extra_column=True):
    run_dir.mkdir()
    table = coefficient_table(fitted)  # the report stage's own writer
    if extra_column:
        table.insert(1, "uncertainty", 0.01)  # other columns may be added (read by name)
    (run_dir / "coefficients.csv").write_text(table.to_csv(index=False))
    cfg = {"magnitudes": {"edges": edges}, "confidence": confidence, "ratio_R": ratio_R}
    (run_dir / "provenance.json").write_text(json.dumps({"kind": "f90_sweep", "config": cfg}))


def test_from_run_reads_coefficients_g_range_p_and_r(tmp_path):
    fitted = {"s0": np.array([2.0, -0.25, 0.0065]), "s1": np.array([0.1, -0.05, 0.013, -0.0005]),
              "s2": np.array([0.03, -0.006])}
    _write_run(tmp_path / "run", fitted, [12, 13, 14, 15, 16, 17])
    prior = Prior.from_run(tmp_path / "run")
    assert (prior.g_min, prior.g_max, prior.confidence, prior.ratio_R) == (12.0, 17.0, 0.8, 5.0)
    # Closed form with these coefficients at G = 14, l = 30, b = -20.
    g, lr, br = 14.0, np.radians(30.0), np.radians(-20.0)
    log_s = (2.0 - 0.25 * g + 0.0065 * g**2) + (0.1 - 0.05 * g + 0.013 * g**2 - 0.0005 * g**3) * abs(np.sin(br)) \
        + (0.03 - 0.006 * g) * np.cos(br) * np.cos(lr)
    assert prior.sigma_parallax(30.0, -20.0, G=14.0).value == pytest.approx(10**log_s, rel=1e-12)
    assert prior.sigma_pm(30.0, -20.0, G=14.0).value == pytest.approx(5.0 * 10**log_s, rel=1e-12)
    # Fainter than the run's range: the value at its faint edge (the paper's rule).
    assert prior.sigma_parallax(30.0, -20.0, G=19.0) == prior.sigma_parallax(30.0, -20.0, G=17.0)
    clamp = Prior.from_run(tmp_path / "run", bright="clamp")
    assert clamp.sigma_parallax(30.0, -20.0, G=5.0) == clamp.sigma_parallax(30.0, -20.0, G=12.0)


def test_from_run_refuses_what_is_not_a_fitted_sweep(tmp_path):
    with pytest.raises(UserInputError, match="no coefficients.csv"):
        Prior.from_run(tmp_path)
    nan = {"s0": np.full(3, np.nan), "s1": np.full(4, np.nan), "s2": np.full(2, np.nan)}
    _write_run(tmp_path / "nan", nan, [13, 14, 15])
    with pytest.raises(UserInputError, match="not finite"):
        Prior.from_run(tmp_path / "nan")
    (tmp_path / "short").mkdir()
    (tmp_path / "short" / "coefficients.csv").write_text("term,fitted\ns0_c0,1.0\n")
    (tmp_path / "short" / "provenance.json").write_text("{}")
    with pytest.raises(UserInputError, match="lacks the terms"):
        Prior.from_run(tmp_path / "short")
    (tmp_path / "sec").mkdir()
    pd.DataFrame({"term": [f"{n}_c{k}" for n, m in (("s0", 3), ("s1", 4), ("s2", 2)) for k in range(m)],
                  "fitted": 0.0}).to_csv(tmp_path / "sec" / "coefficients.csv", index=False)
    (tmp_path / "sec" / "provenance.json").write_text(json.dumps({"kind": "secondary", "config": {}}))
    with pytest.raises(UserInputError, match="secondary"):
        Prior.from_run(tmp_path / "sec")
