"""The built-in galaxy model against published facts about the real sky (its calibration targets).

References and their uncertainties: :mod:`mcsweep.validation.published_counts` and
docs/galaxy_model.md. Tolerances are the calibration's targets; each comparison also prints
the published number's own uncertainty (Poisson and systematic).
"""

import numpy as np
import pytest

from mcsweep.population import GalaxyModel
from mcsweep.validation import published_counts as pc

#: Calibration targets of besancon-r03-2 to r03-4 (docs/galaxy_model.md).
COUNT_TOL = 0.10        # all-sky counts per G magnitude
LOCAL_TOL = 0.20        # local (GCNS) density
BEAM_TOL = 0.10         # paper Table 1 beam vs 458 GUMS stars
GUMS_BEAM_COUNT = 458
LF_TOL = 0.20           # local luminosity function per 1-mag bin
#: Relative rounding of a density published with 3 significant digits (CNS5: 7.99e-2, 4.03e-3).
CNS5_ROUNDING = 0.005 / 4.03
#: The target against the real sky's counts: within 8 %, what the model met when Gaia DR3's
#: counts became the reference (docs/galaxy_model.md).
GAIA_COUNT_TOL = 0.08
#: G bins compared with Tycho-2 (V < 10.25 with G - V = -0.25: the Tycho-2 part of the
#: compilation, its magnitudes V-like and complete).
MET_BINS = list(range(4, 9)) + [pytest.param(9, marks=pytest.mark.xfail(strict=True, reason=(
    "besancon-r03-6: 0.885 x Tycho-2 at G = 9-10 (r03-5: 0.935), as against Gaia DR3 (0.909) "
    "(docs/galaxy_colours.md)")))]
#: G bins compared with Gaia DR3's own counts (bundled file below G = 10, quoted counts to 13;
#: G = 13-14 rests on a rounded "~17M", +-10 %: shown in the report, not tested). G = 9-13:
#: measured outside the target since besancon-r03-6 (docs/galaxy_colours.md).
GAIA_BINS = list(range(4, 9)) + [pytest.param(g, marks=pytest.mark.xfail(strict=True, reason=(
    "besancon-r03-6: 0.909, 0.889, 0.884, 0.886 x Gaia DR3 at G = 9-13 (r03-5: 0.961-1.040). The "
    "isochrones' evolved stars are fainter than the Wielen/Allen giant bins; the thick disc's "
    "G = 11-12 stars fell from 432 000 to 266 000 (docs/galaxy_colours.md)"))) for g in (9, 10, 11, 12)]


@pytest.fixture(scope="module")
def model():
    return GalaxyModel()


@pytest.mark.parametrize("g", MET_BINS)
def test_all_sky_counts_per_magnitude_match_tycho2(model, g):
    row = pc.count_comparison(model, [g]).iloc[0]
    print(f"G {g}-{g + 1}: model {row.model:.4g}, published {row.published:.4g} "
          f"+- {100 * row.rel_uncertainty:.0f} %")
    assert abs(row.ratio - 1.0) <= COUNT_TOL


@pytest.mark.parametrize("g", GAIA_BINS)
def test_all_sky_counts_per_magnitude_match_gaia_dr3(model, g):
    row = pc.count_comparison(model, [g]).iloc[0]
    if np.isnan(row.gaia_dr3):
        pytest.skip("Gaia DR3's counts below G = 10 need the optional extra realsky")
    print(f"G {g}-{g + 1}: model {row.model:.4g}, Gaia DR3 {row.gaia_dr3:.4g} "
          f"+- {100 * row.gaia_rel_uncertainty:.1f} %")
    assert abs(row.ratio_gaia - 1.0) <= GAIA_COUNT_TOL


def test_the_compilation_s_ucac4_part_is_too_bright_against_gaia_dr3():
    # two published sources of the same sky: the quoted Gaia DR3 counts at G = 11-13 lie
    # 20 % or more below the Tycho-2/UCAC4 compilation, well beyond the quoted digits and the
    # G - V systematic's low side; at G = 10-11 (V = 10.25-11.25, the seam) by 13 %; the
    # G = 13-14 bin (+-10 %) only shown
    g = [10, 11, 12, 13]
    gaia, err = pc.gaia_dr3_counts_per_g(g)
    assert np.all(err[:3] / gaia[:3] < 0.01)
    low_side = pc.published_counts_per_g(np.array(g, float), pc.G_MINUS_V + pc.G_MINUS_V_SYST)
    assert np.all(pc.published_counts_per_g(np.array(g[1:3], float)) / gaia[1:3] > 1.2)
    assert np.all(low_side[1:3] / gaia[1:3] > 1.10)
    # the quoted N(G < 10) is the bundled file's own count (when the extra is installed)
    from mcsweep.population import gaia_bright

    if gaia_bright.have_catalogue():
        n_gaia = int((~gaia_bright.load_gaia_bright().from_hipparcos).sum())
        assert n_gaia == pytest.approx(pc.GAIA_DR3_CUMULATIVE_G[0][1], abs=pc.GAIA_DR3_CUMULATIVE_G[0][2])


def test_cns5_published_densities_match_its_counts():
    # the CNS5 abstract's densities are its 25 pc counts over the sphere (two published
    # forms of one fact); the densities are rounded to 3 digits
    v25 = 4.0 / 3.0 * np.pi * 25.0 ** 3
    assert pc.CNS5_25PC["stars"] / v25 == pytest.approx(pc.CNS5_STARS_PC3, rel=CNS5_ROUNDING)
    assert pc.CNS5_25PC["white_dwarfs"] / v25 == pytest.approx(pc.CNS5_WD_PC3, rel=CNS5_ROUNDING)


def test_published_bright_counts_agree_with_hipparcos():
    # the two published sources of the bright end agree (Hipparcos N(V<6), N(V<7))
    for v, n_hip in ((6, 4968), (7, 15328)):
        assert pc.cumulative_count(v) == pytest.approx(n_hip, rel=COUNT_TOL)


def test_local_density_matches_gcns(model):
    n = pc.local_sources_within(model)
    print(f"100 pc, M_G < {pc.GCNS_MG_LIMIT}: model {n:.0f}, GCNS {pc.GCNS_WITHIN_100PC:.0f} "
          f"+- {pc.GCNS_SYST:.0f}")
    assert n == pytest.approx(pc.GCNS_WITHIN_100PC, rel=LOCAL_TOL)


@pytest.mark.xfail(strict=True, reason=(
    "besancon-r03-6: N(G < 21) = 1.71e9, 0.94 x Gaia DR3's 1.81e9 sources (r03-5: 1.93e9); the "
    "all-sky counts are 0.88-0.91 x DR3's at G = 9-13 (docs/galaxy_colours.md)"))
def test_faint_total_at_least_gaia_dr3(model):
    # Gaia DR3 is incomplete at G = 20-21: a model must hold at least as many sources
    assert model.expected_count(0, 90, 180, -5, 21) >= pc.DR3_TOTAL


def test_faint_total_against_gums(model):
    # GUMS-10 is a model itself (a 10 % target); 1.05 x with besancon-r03-5, 1.23 x with
    # r03-4's disc dust
    assert model.expected_count(0, 90, 180, -5, 20) == pytest.approx(pc.GUMS_G20, rel=COUNT_TOL)


def test_bright_main_sequence_lf_matches_bovy_per_bin(model):
    # A calibration check, not an independent validation: Bovy's mass function is the
    # model's own input above 1 Msun; this catches its wiring (mass-magnitude relation,
    # bins, multiplicity), and the all-sky counts and censuses test the result.
    comp = pc.local_lf_comparison(model).dropna(subset=["bovy_ms"])
    assert len(comp) >= 2
    for row in comp.itertuples():
        print(f"M_G {row.M_G_lo}-{row.M_G_lo + 1}: model {row.model_dwarfs:.3g}, "
              f"Bovy 2017 {row.bovy_ms:.3g} pc^-3")
        assert row.ratio_to_bovy == pytest.approx(1.0, abs=LF_TOL)


def test_local_content_against_independent_censuses(model):
    census = pc.local_census_comparison(model).set_index("quantity")
    for name, row in census.iterrows():
        print(f"{name}: model {row.model:.4g}, published {row.published:.4g} +- {row.uncertainty:.2g}")
    # GCNS within 60 pc (either reading of the poster's M_G cut) and CNS5 within 25 pc
    for name in ("GCNS 60 pc, sources M_G < 15", "GCNS 60 pc, all sources (other reading)",
                 "CNS5 25 pc, stars (model sources)"):
        assert census.loc[name, "ratio"] == pytest.approx(1.0, abs=LOCAL_TOL)
    # 20 CNS5 giants: Poisson +-4.5; the model's evolved stars beyond the subgiant branch (from
    # the isochrones and the components' mass densities, no local giant density imposed) within
    # 2 sigma
    g = census.loc["CNS5 25 pc, giants (model evolved stars beyond the subgiant branch)"]
    assert abs(g.model - g.published) <= 2 * g.uncertainty


def test_table1_beam_within_target(model):
    n = model.expected_count(245.7, 46.5, 1.0, 14.5, 15.5)
    print(f"Table 1 beam: {n:.0f} (GUMS {GUMS_BEAM_COUNT} +- {np.sqrt(GUMS_BEAM_COUNT):.0f})")
    assert n == pytest.approx(GUMS_BEAM_COUNT, rel=BEAM_TOL)


@pytest.mark.parametrize("cls", [
    # A stars: 5.2e-4 sources pc^-3 since besancon-r03-6 (Bovy's mass function over the whole main
    # sequence, M_V <= 1 included) against Mamajek's 4.9e-4 +- 0.66e-4; r03-5 held 3.7e-4 (0.75 x)
    "A", "F", "G", "K", "M", "M + white dwarfs",
    pytest.param("M + white dwarfs (CNS5)", marks=pytest.mark.xfail(
        strict=True, reason="model 7.98e-2 stars pc^-3 in the M range (sources x 1.27) = 1.30 x "
        "CNS5's M dwarfs + white dwarfs, 6.16e-2 +- 0.09e-2 (Golovin et al. 2023: about 72 % of "
        "7.99e-2, + 4.03e-3); 1.02 x with one star per source; RECONS + Holberg: 1.10 x "
        "(docs/galaxy_model.md)"))])
def test_local_density_per_spectral_class(model, cls):
    row = pc.local_density_by_class(model).set_index("cls").loc[cls]
    print(f"{cls} (M_G {row.M_G_lo:.2f}-{row.M_G_hi:.2f}, {row.counts}): model {row.model:.3g}, "
          f"published {row.published:.3g} +- {row.uncertainty:.2g} pc^-3 ({row.sample})")
    assert row.ratio == pytest.approx(1.0, abs=LF_TOL)
