"""The galaxy model's evolved stars from the PARSEC + COLIBRI isochrones (population.galaxy.evolved):
the vendored grid against facts read in the original file, the age and metallicity weights in
closed form, the turn-off masses against stellar-evolution facts, and the local giant density
the synthesis predicts against two censuses it was not fitted to."""

import numpy as np
import pytest
from scipy.stats import norm

from mcsweep.population import GalaxyModel
from mcsweep.population.galaxy import colours as C
from mcsweep.population.galaxy import evolved as E
from mcsweep.population.galaxy import parameters as P
from mcsweep.population.galaxy.luminosity import MG_MAX, MG_MIN, MG_STEP, evolved_lf

#: Weights are sums of probabilities: to rounding.
SUM_TOL = 1e-12
#: Discretisation of the isochrone grid (0.12 dex in age, 0.25 dex in [M/H]) on a weighted mean.
GRID_MEAN_TOL = 0.02


def test_the_grid_is_the_published_parsec_grid():
    g = E.load_evolved_isochrones()
    # 11 metallicities -2.19 ... +0.30 in 0.25 dex, 36 ages log t = 6.00 ... 10.20 in 0.12
    assert g.mh.size == 11 and g.mh[0] == pytest.approx(-2.19174) and g.mh[-1] == pytest.approx(0.3)
    assert np.allclose(np.diff(g.mh[1:]), 0.25) and np.allclose(g.log_age, 6.0 + 0.12 * np.arange(36))
    assert g.m_g.size == 79_946 and set(np.unique(g.label)) == set(range(1, 9))
    # a metal-rich 4 Gyr isochrone: its red giant branch ends among the M giants, its thermally
    # pulsing AGB (carbon stars) redder still; the red clump (core helium burning) near M_G 0.5
    iso = (np.isclose(g.mh[g.i_mh], 0.05)) & (np.isclose(g.log_age[g.i_age], 9.6))
    assert g.bp_rp[iso & (g.label == 3)].max() > 3.0
    assert g.bp_rp[iso & (g.label == 8)].max() > 5.0
    assert np.median(g.m_g[iso & (g.label == 4)]) == pytest.approx(0.5, abs=0.5)
    # every isochrone starts with its last main-sequence row, of no mass step
    first = np.r_[True, np.diff(g.i_mh * 36 + g.i_age) != 0]
    assert np.all(g.label[first] == 1) and np.all(g.dm[first] == 0.0) and np.all(g.dm >= 0.0)


def test_age_weights_are_a_constant_star_formation_rate_or_an_interpolation():
    la = E.load_evolved_isochrones().log_age
    w = E.age_weights((1.0, 2.0), la)
    assert w.sum() == pytest.approx(1.0, abs=SUM_TOL)
    # the cells of log t = 9.12 and 9.24 lie wholly inside 1-2 Gyr: weight = cell length / 1 Gyr
    for node in (9.12, 9.24):
        i = int(np.argmin(np.abs(la - node)))
        cell = 10 ** (la[i] + 0.06) - 10 ** (la[i] - 0.06)
        assert w[i] == pytest.approx(cell / 1e9, rel=1e-9)
    assert np.all(w[la < 8.9] == 0) and np.all(w[la > 9.4] == 0)
    one = E.age_weights((11.0, 11.0), la)
    assert one.sum() == pytest.approx(1.0, abs=SUM_TOL) and np.count_nonzero(one) == 2
    assert np.dot(one, la) == pytest.approx(np.log10(11e9), abs=SUM_TOL)


@pytest.mark.parametrize("feh", [(-0.78, 0.30), (-1.78, 0.50), (0.01, 0.12)])
def test_metallicity_weights_are_the_gaussian_over_the_grid_cells(feh):
    mh = E.load_evolved_isochrones().mh
    w = E.metallicity_weights(feh, mh)
    edges = np.r_[-np.inf, 0.5 * (mh[1:] + mh[:-1]), np.inf]
    expected = np.diff(norm.cdf(edges, *feh))
    assert w == pytest.approx(expected / expected.sum(), abs=SUM_TOL)
    if feh[0] - 2 * feh[1] > mh[0]:   # tails inside the grid: the mean carries over
        assert np.dot(w, mh) == pytest.approx(feh[0], abs=GRID_MEAN_TOL + 0.25 * feh[1])


def test_turnoff_masses_follow_stellar_evolution():
    ages = np.array([0.1, 0.5, 1.0, 2.0, 5.0, 10.0])
    m = E.turnoff_mass(ages, 0.0)
    assert np.all(np.diff(m) < 0)
    # the Sun leaves the main sequence at about 10 Gyr (textbook): a 10 Gyr solar turn-off near 1 Msun
    assert m[-1] == pytest.approx(1.0, abs=0.05)
    # metal-poor stars of the same mass live shorter: lower turn-off mass at every age
    assert np.all(E.turnoff_mass(ages, -1.5) < m)


def test_local_giants_agree_with_two_censuses_the_synthesis_was_not_fitted_to():
    # the evolved stars beyond the subgiant branch at the Sun, from R03's mass densities, the
    # IMFs and the isochrones (no local giant density imposed): Bovy (2017) 3.9e-4 +- 0.1e-4 pc^-3
    # (Gaia DR1 giants), CNS5 20 red giants within 25 pc (Golovin et al. 2023), +-4.5 (Poisson)
    edges = np.arange(MG_MIN, MG_MAX + 0.5 * MG_STEP, MG_STEP)
    local = [c for c in P.COMPONENTS if c.law != "bulge" and c.lf_part != "dwarfs"]
    n = sum(evolved_lf(c, edges, subgiants=False).sum() for c in local)
    assert n == pytest.approx(3.9e-4, rel=0.15)
    assert abs(n * 4.0 / 3.0 * np.pi * 25.0 ** 3 - 20) <= 2 * np.sqrt(20)


def test_old_populations_reach_the_m_giants_and_the_agb():
    # the old thin disc's evolved stars go to BP - RP ~ 4 and beyond (M giants, thermally
    # pulsing AGB), which the BaSTI-IAC 3 Gyr isochrone of besancon-r03-5 stopped short of (2.13)
    q = C.evolved_colour_quantiles(P.THIN_DISC_GIANTS[-1])
    assert q[:, -1].max() > 4.0
    # the red clump (M_G ~ 0.5) of the old disc: BP - RP about 1.1-1.25 (Ruiz-Dern et al. 2018)
    clump = q[np.argmin(np.abs(C.EVOLVED_MG_GRID - 0.5)), 50]
    assert 1.05 < clump < 1.3
    # the halo's horizontal branch is bluer than the disc's clump
    halo = C.evolved_colour_quantiles(P.HALO)[np.argmin(np.abs(C.EVOLVED_MG_GRID - 0.5)), 50]
    assert halo < clump - 0.3


def test_dwarf_only_components_have_no_evolved_stars_and_subgiants_false_drops_the_branch():
    edges = np.arange(MG_MIN, MG_MAX + 0.5 * MG_STEP, MG_STEP)
    comp = P.THIN_DISC_GIANTS[4]
    with_, without = evolved_lf(comp, edges), evolved_lf(comp, edges, subgiants=False)
    assert np.all(without <= with_) and without.sum() < 0.8 * with_.sum()
    assert not C.evolved_colour_quantiles(P.THIN_DISC[4]).any()


def test_giants_are_reddened_with_the_law_for_the_upper_hr_diagram():
    x, a0 = np.array([1.2, 1.2]), np.array([1.0, 1.0])
    ms, top = C.reddening_bp_rp(x, a0, np.array([False, True]))
    assert ms == C.reddening_bp_rp(1.2, 1.0)
    # the BPRP rows of the ESA file Fitz19_EDR3_HRDTop.csv as published (Intercept, X, X2, X3, A,
    # A2, A3, XA, AX2, XA2), transcribed here apart from the code's constants
    rows = {"kBP": "1.15477509956089,-0.0860151175561996,-0.0302071198654238,0.0140420820336445,"
                   "-0.0223968266786066,0.000823544766886717,-1.20366204386921e-05,0.00699684361199003,"
                   "-0.000499920649896623,-0.000148686538559682",
            "kRP": "0.662595389120923,-0.0167121614962357,-0.00144198404916194,-0.00133749382473256,"
                   "-0.00655783097133718,3.36125225635362e-05,1.61356747065676e-06,2.20748538619438e-05,"
                   "0.000178453487002225,1.0336186431516e-05"}
    X, A = 1.2, 1.0
    terms = (1, X, X ** 2, X ** 3, A, A ** 2, A ** 3, X * A, A * X ** 2, X * A ** 2)
    k = {band: sum(float(c) * t for c, t in zip(row.split(","), terms)) for band, row in rows.items()}
    assert top == pytest.approx((k["kBP"] - k["kRP"]) * A, rel=1e-12)
    assert top != pytest.approx(ms, rel=1e-6)  # the two laws differ
    # the default model reddens its evolved stars with it, r03-5 with the main sequence's
    m = GalaxyModel()
    assert m.colours.upper_hrd_law and not GalaxyModel(evolved_stars="wielen").colours.upper_hrd_law


def test_unknown_evolved_stars_is_one_clear_line():
    from mcsweep.errors import UserInputError

    with pytest.raises(UserInputError, match="evolved_stars='basti'.*expected one of"):
        GalaxyModel(evolved_stars="basti")
