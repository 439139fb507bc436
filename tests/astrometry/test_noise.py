"""Noise model numbers against the published formulas they come from."""

import numpy as np
import pytest

from mcsweep.astrometry.design import design_matrix, reference_epoch, years_since
from mcsweep.astrometry.noise import G_MAX, NoiseModel
from mcsweep.astrometry.solve import normal_equations, solve_no_prior
from mcsweep.errors import UserInputError
from mcsweep.scanning.ephemeris import gaia_position_au

#: Agreement with the hand evaluation of Perryman et al. (2014) Eqs. 1-3, relative.
FORMULA_RTOL = 1e-12
#: The same formula evaluated for an array and for a scalar: numpy's vector and scalar
#: code paths may differ in the last bits.
RTOL_PATHS = 1e-13
#: Accepted band of (model parallax uncertainty) / (Gaia EDR3 relation), dimensionless.
EDR3_RATIO_MIN, EDR3_RATIO_MAX = 0.4, 1.5


def test_al_matches_perryman_2014_by_hand():
    # G = 15: z = 1, sigma_eta^2 = 53000 + 310 = 53310 uas^2,
    # sigma_fov^2 = 53310/9 + 20^2 + 20^2 = 5923.33 + 800 = 6723.33 uas^2 -> 81.996 uas.
    # G = 20: z = 100, sigma_eta^2 = 5.3e6 + 3.1e6 = 8.4e6, sigma_fov^2 = 933333.3 + 800.
    # G = 12 (bright floor): z = 10^-1.2 = 0.0630957, sigma_eta^2 = 3344.07 + 1.2341.
    expected_mas = 1e-3 * np.sqrt([53310 / 9 + 800, 8.4e6 / 9 + 800,
                                   (53000 * 10**-1.2 + 310 * 10**-2.4) / 9 + 800])
    np.testing.assert_allclose(NoiseModel().sigma_al_mas([15.0, 20.0, 12.0]), expected_mas, rtol=FORMULA_RTOL)
    np.testing.assert_allclose(NoiseModel().sigma_al_mas(15.0), 0.081996, rtol=1e-5)


def test_bright_stars_use_the_g12_value():
    nm = NoiseModel()
    np.testing.assert_allclose(nm.sigma_al_mas([3.0, 8.0, 11.99]), nm.sigma_al_mas(12.0), rtol=RTOL_PATHS, atol=0)
    np.testing.assert_allclose(nm.sigma_ac_mas([3.0, 8.0]), nm.sigma_ac_mas(12.0), rtol=RTOL_PATHS, atol=0)


def test_ac_is_much_less_precise_than_al():
    nm = NoiseModel()
    g = np.linspace(3.0, G_MAX, 200)
    ratio = nm.sigma_ac_mas(g) / nm.sigma_al_mas(g)
    assert np.all(ratio >= 2.9)  # 2D windows (G < 13): image 3x wider across scan
    assert np.all(ratio[g >= 13.0] >= 6.0)  # G >= 13: sky-mapper window only
    # By hand at G = 15: sigma_ac^2 = 9 (53310 + 800) uas^2.
    np.testing.assert_allclose(nm.sigma_ac_mas(15.0), 1e-3 * np.sqrt(9 * (53310 + 800)), rtol=FORMULA_RTOL)


def test_scale_factors_and_config():
    base = NoiseModel()
    scaled = NoiseModel.from_config({"name": "gaia", "al_scale": 2.0, "ac_scale": 0.5, "use_ac": False})
    g = np.array([9.0, 14.0, 19.0])
    np.testing.assert_allclose(scaled.sigma_al_mas(g), 2.0 * base.sigma_al_mas(g), rtol=1e-15)
    np.testing.assert_allclose(scaled.sigma_ac_mas(g), 0.5 * base.sigma_ac_mas(g), rtol=1e-15)
    al, ac = scaled.design_sigmas(g)
    assert al.shape == (3, 1) and ac is None
    assert base.design_sigmas(g)[1].shape == (3, 1)


def test_al_floor_adds_in_quadrature_by_hand():
    # G = 15: sigma_fov^2 = 6723.33 uas^2 (test above); floor 0.039 mas = 39 uas:
    # sigma^2 = 6723.33 + 1521 = 8244.33 uas^2 -> 90.798 uas. With al_scale = 2 the
    # published part doubles, the floor does not: 4 * 6723.33 + 1521.
    # G = 12: (3344.07 + 1.2341) / 9 + 800 + 1521 uas^2.
    floor = NoiseModel(al_floor_mas=0.039)
    expected_mas = 1e-3 * np.sqrt([53310 / 9 + 800 + 39.0**2,
                                   (53000 * 10**-1.2 + 310 * 10**-2.4) / 9 + 800 + 39.0**2])
    np.testing.assert_allclose(floor.sigma_al_mas([15.0, 12.0]), expected_mas, rtol=FORMULA_RTOL)
    np.testing.assert_allclose(floor.sigma_al_mas(15.0), 0.090798, rtol=1e-5)
    scaled = NoiseModel(al_scale=2.0, al_floor_mas=0.039)
    np.testing.assert_allclose(scaled.sigma_al_mas(15.0), 1e-3 * np.sqrt(4 * (53310 / 9 + 800) + 39.0**2),
                               rtol=FORMULA_RTOL)
    # AC is not touched by the AL floor.
    np.testing.assert_array_equal(floor.sigma_ac_mas([12.0, 15.0]), NoiseModel().sigma_ac_mas([12.0, 15.0]))


def test_zero_floor_is_the_published_model_exactly():
    g = np.linspace(3.0, G_MAX, 301)
    for kw in (dict(), dict(al_scale=1.7)):
        np.testing.assert_array_equal(NoiseModel(al_floor_mas=0.0, **kw).sigma_al_mas(g),
                                      NoiseModel(**kw).sigma_al_mas(g))
    cfg = NoiseModel.from_config({"name": "gaia", "al_scale": 1.0, "ac_scale": 1.0, "use_ac": True})
    assert cfg.al_floor_mas == 0.0
    assert NoiseModel.from_config({"al_floor_mas": 0.039}).al_floor_mas == 0.039


@pytest.mark.parametrize("kwargs", [dict(al_scale=0.0), dict(ac_scale=-1.0), dict(al_scale=float("nan")),
                                    dict(use_ac="yes"), dict(al_floor_mas=-0.01),
                                    dict(al_floor_mas=float("nan")), dict(al_floor_mas=float("inf")),
                                    dict(al_floor_mas="0.1")])
def test_rejects_bad_parameters(kwargs):
    with pytest.raises(UserInputError) as exc:
        NoiseModel(**kwargs)
    assert "\n" not in str(exc.value) and next(iter(kwargs)) in str(exc.value)


@pytest.mark.parametrize("g", [21.5, np.nan])
def test_rejects_magnitudes_outside_the_model(g):
    with pytest.raises(UserInputError, match="G"):
        NoiseModel().sigma_al_mas([15.0, g])


def test_parallax_precision_is_close_to_gaia_edr3():
    """Cross-check against published performance (Lindegren et al. 2021, A&A 649, A2).

    Gaia (E)DR3 sky-averaged parallax uncertainty: sqrt(40 + 800 z + 30 z^2) uas with
    z = 10^(0.4 (max(G, 13) - 15)) for 34 months of data (ESA Gaia science performance
    pages; PyGaia). Simulating ~35 FoV transits over the EDR3 interval with random scan
    angles, the model's median formal parallax uncertainty lies within a factor 0.4-1.5
    of it: ~1.0 at G = 13, ~0.5 at G = 20 (the pre-launch model of Perryman et al. is
    optimistic for faint stars, where the real data also suffer from data gaps and
    crowding).
    """
    rng = np.random.default_rng(2021)
    n, k = 500, 35
    jd = 2456892.375 + 1009.0 * rng.uniform(size=(n, k))  # EDR3 astrometry interval
    ra, dec = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))
    psi = rng.uniform(0, 360, (n, k))
    t_yr = years_since(jd, reference_epoch(jd))
    obs = gaia_position_au(jd)
    nm = NoiseModel()
    for g in (13.0, 15.0, 17.0, 19.0, 20.0):
        sig_al, sig_ac = nm.design_sigmas(np.full(n, g))
        A = design_matrix(ra, dec, t_yr, psi, obs, sigma_al_mas=sig_al, sigma_ac_mas=sig_ac)
        sol = solve_no_prior(*normal_equations(A, np.zeros(A.shape[:2])))
        model_uas = 1e3 * np.median(np.sqrt(sol.cov[:, 2, 2]))
        z = 10 ** (0.4 * (max(g, 13.0) - 15.0))
        edr3_uas = np.sqrt(40 + 800 * z + 30 * z * z)
        assert EDR3_RATIO_MIN < model_uas / edr3_uas < EDR3_RATIO_MAX, (g, model_uas, edr3_uas)
