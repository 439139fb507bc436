"""GalaxyModel: exact expectations, unbiased and reproducible sampling, user errors."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from mcsweep.errors import UserInputError
from mcsweep.population import COLUMNS, GalaxyModel
from mcsweep.population.galaxy.model import DRAW_BLOCK_STARS

BEAM = (245.7, 46.5, 1.0)               # paper Table 1: (l, b, radius) in deg
EXPECTATION_REL_TOL = 1e-9               # sums of the same tabulated weights
POISSON_SIGMAS = 5.0                     # allowed deviation of a Poisson count
KS_P_MIN = 1e-3                          # two-sample / goodness-of-fit tests
MU_PLX_RANGE = (6.0, 15.0)               # 1/yr: paper Sect. 3.1 "about 10 /yr in GUMS"


@pytest.fixture(scope="module")
def model():
    return GalaxyModel()


def test_expected_count_is_additive_in_magnitude(model):
    a = model.expected_count(*BEAM, 14.5, 15.0)
    b = model.expected_count(*BEAM, 15.0, 15.5)
    assert a + b == pytest.approx(model.expected_count(*BEAM, 14.5, 15.5), rel=EXPECTATION_REL_TOL)
    by_pop = model.expected_count_by_population(*BEAM, 14.5, 15.5)
    assert sum(by_pop.values()) == pytest.approx(a + b, rel=EXPECTATION_REL_TOL)


def test_whole_sky_radius_and_symmetry(model):
    n180 = model.expected_count(0, 90, 180, 10, 11)
    assert model.expected_count(123, -40, 250, 10, 11) == pytest.approx(n180, rel=1e-3)
    # north and south Galactic caps differ only through z_sun: within 10 %
    north = model.expected_count(0, 90, 30, 14, 15)
    south = model.expected_count(0, -90, 30, 14, 15)
    assert 0.9 < north / south < 1.1


def test_counts_scale_with_cone_area_at_high_latitude(model):
    small = model.expected_count(100, 60, 1.0, 15, 16)
    big = model.expected_count(100, 60, 2.0, 15, 16)
    area_ratio = (1 - np.cos(np.radians(2.0))) / (1 - np.cos(np.radians(1.0)))
    assert big / small == pytest.approx(area_ratio, rel=0.05)


def test_sample_matches_the_query_and_contract(model):
    df = model.sample_cone(*BEAM, 14.5, 15.5, np.random.default_rng(1))
    assert list(df.columns) == [*COLUMNS, "bp_rp"]  # the model adds its stars' colour
    assert isinstance(df["population"].dtype, pd.CategoricalDtype)
    assert df["phot_g_mean_mag"].between(14.5, 15.5, inclusive="left").all()
    sep = np.degrees(np.arccos(np.clip(
        np.sin(np.radians(df.b)) * np.sin(np.radians(BEAM[1]))
        + np.cos(np.radians(df.b)) * np.cos(np.radians(BEAM[1])) * np.cos(np.radians(df.l - BEAM[0])),
        -1, 1)))
    assert (sep <= BEAM[2] + 1e-9).all()
    assert np.allclose(df.parallax * df.distance_pc, 1000.0)
    assert np.isfinite(df[list(COLUMNS[:-1])].to_numpy()).all()
    n_exp = df.attrs["expected_count"]
    assert abs(df.attrs["n_in_cone"] - n_exp) < POISSON_SIGMAS * np.sqrt(n_exp)


def test_table1_beam_proper_motion_to_parallax_ratio(model):
    df = model.sample_cone(*BEAM, 14.5, 15.5, np.random.default_rng(2))
    ratio = np.median(np.hypot(df.pmra, df.pmdec) / df.parallax)
    assert MU_PLX_RANGE[0] < ratio < MU_PLX_RANGE[1]


def test_sampled_magnitudes_follow_the_expected_counts(model):
    edges = np.linspace(12.0, 16.0, 9)
    expect = np.array([model.expected_count(30, 20, 1.0, a, b) for a, b in zip(edges[:-1], edges[1:])])
    df = model.sample_cone(30, 20, 1.0, 12.0, 16.0, np.random.default_rng(3), max_stars=20000)
    got = np.histogram(df.phot_g_mean_mag, edges)[0]
    chi2 = stats.chisquare(got, expect / expect.sum() * got.sum())
    assert chi2.pvalue > KS_P_MIN


def test_cap_keeps_an_unbiased_subsample(model):
    full = model.sample_cone(30, 5, 1.0, 16, 17, np.random.default_rng(4))
    capped = model.sample_cone(30, 5, 1.0, 16, 17, np.random.default_rng(5), max_stars=2000)
    assert len(capped) == 2000 and capped.attrs["n_in_cone"] > 2000
    assert abs(capped.attrs["n_in_cone"] - full.attrs["expected_count"]) < POISSON_SIGMAS * np.sqrt(
        full.attrs["expected_count"])
    for col in ("distance_pc", "phot_g_mean_mag", "pmra"):
        assert stats.ks_2samp(full[col], capped[col]).pvalue > KS_P_MIN


def test_reproducible_and_independent_of_chunking():
    a, b = GalaxyModel(), GalaxyModel()
    b.chunk_stars = DRAW_BLOCK_STARS          # one block per chunk instead of four
    n = 2 * DRAW_BLOCK_STARS + 123
    da = a.sample_cone(0, 3, 2.0, 14, 18, np.random.default_rng(6), max_stars=n)
    db = b.sample_cone(0, 3, 2.0, 14, 18, np.random.default_rng(6), max_stars=n)
    assert len(da) == n
    pd.testing.assert_frame_equal(da, db, check_exact=True)
    dc = a.sample_cone(0, 3, 2.0, 14, 18, np.random.default_rng(7), max_stars=n)
    assert not np.array_equal(da.ra.to_numpy(), dc.ra.to_numpy())


def test_sample_sky_and_empty_draw(model):
    df = model.sample_sky(8, 9, np.random.default_rng(8), max_stars=3000)
    assert len(df) == 3000
    # all sky: both hemispheres and a spread of latitudes
    assert (df.b > 30).any() and (df.b < -30).any()
    with pytest.raises(UserInputError, match="max_stars"):
        model.sample_sky(0, 21, np.random.default_rng(8))
    none = model.sample_cone(*BEAM, 4.0, 4.001, np.random.default_rng(9))
    assert len(none) == 0 and list(none.columns) == [*COLUMNS, "bp_rp"]


def test_extinction_and_thin_disc_parameters_act_in_the_expected_direction():
    base = GalaxyModel().expected_count(30, 2, 1.0, 16, 17)
    clear = GalaxyModel(extinction=False).expected_count(30, 2, 1.0, 16, 17)
    thin = GalaxyModel(thin_disc_scale_height_factor=0.8).expected_count(*BEAM, 14.5, 15.5)
    assert clear > 2 * base
    assert thin < GalaxyModel().expected_count(*BEAM, 14.5, 15.5)
    only_halo = GalaxyModel(components=["halo"]).expected_count_by_population(*BEAM, 14.5, 15.5)
    assert set(only_halo) == {"halo"}


def test_giant_thickness_factor_scales_the_giants_discs_and_velocities_only():
    from mcsweep.population.galaxy import parameters as P
    default, thick = GalaxyModel(), GalaxyModel(giant_thickness_factor=2.0 * P.GIANT_THICKNESS_FACTOR)
    assert default.components == P.COMPONENTS
    for c0, c1 in zip(default.components, thick.components):
        if c0.lf_part == "giants":
            assert c1.eps == pytest.approx(c0.eps * 2.0)
            assert np.allclose(c1.sigma_uvw, np.array(c0.sigma_uvw) * np.sqrt(2.0))
        else:
            assert c1 == c0
    # the local luminosity function does not depend on the giants' thickness
    assert np.array_equal(default.lf.cdf, thick.lf.cdf)
    # thicker giants: more bright stars at high latitude
    assert thick.expected_count(0, 90, 10, 6, 8) > default.expected_count(0, 90, 10, 6, 8)


@pytest.mark.parametrize("kwargs, word", [
    ({"thin_disc_scale_height_factor": -1}, "thin_disc_scale_height_factor"),
    ({"giant_thickness_factor": 0}, "giant_thickness_factor"),
    ({"components": ["disc"]}, "components"),
    ({"extinction": "yes"}, "extinction"),
    ({"count": "exact"}, "count"),
    ({"bogus": 1}, "bogus"),
])
def test_bad_parameters_raise_one_line(kwargs, word):
    with pytest.raises(UserInputError) as err:
        GalaxyModel(**kwargs)
    assert word in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("args, word", [
    ((0, 95, 1, 10, 11), "b_deg"),
    ((0, 0, 0, 10, 11), "radius_deg"),
    ((0, 0, 1, 12, 11), "g_min"),
    ((0, 0, 1, float("nan"), 11), "g_min"),
])
def test_bad_queries_raise(model, args, word):
    with pytest.raises(UserInputError, match=word):
        model.expected_count(*args)
    with pytest.raises(UserInputError, match="max_stars"):
        model.sample_cone(0, 0, 1, 10, 11, np.random.default_rng(0), max_stars=0)
    with pytest.raises(UserInputError, match="rng"):
        model.sample_cone(0, 0, 1, 10, 11, rng=42)


def test_young_disc_thickness_factor_scales_the_young_bins_only():
    from mcsweep.population.galaxy import parameters as P
    default = GalaxyModel()
    thicker = GalaxyModel(young_disc_thickness_factor=2.0 * P.YOUNG_DISC_THICKNESS_FACTOR)
    young = 0
    for c0, c1 in zip(default.components, thicker.components):
        if c0.label == "thin_disc" and c0.age_gyr[1] <= P.YOUNG_DISC_MAX_AGE_GYR:
            young += 1
            assert c1.eps == pytest.approx(c0.eps * 2.0)
            assert np.allclose(c1.sigma_uvw, np.array(c0.sigma_uvw) * np.sqrt(2.0))
        else:
            assert c1 == c0
    assert young == 6   # three age bins and their giants' companions
    assert np.array_equal(default.lf.cdf, thicker.lf.cdf)
    assert thicker.expected_count(0, 90, 10, 6, 8) > default.expected_count(0, 90, 10, 6, 8)
