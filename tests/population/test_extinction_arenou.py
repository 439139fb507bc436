"""The Arenou, Grenon & Gomez (1992, A&A 258, 104) extinction model (default since besancon-r03-5).

References: the paper's Eqs. 5 / 5bis evaluated here in closed form from the table's own
coefficients, and the two worked examples of the IvS KU Leuven implementation's
documentation, (l, b) = (10.2, 59.0) without distance -> A_V = 0.05 and (107.05, -34.93)
at 144.65 pc -> 0.15 (both rounded to 0.01 mag there).
"""

import numpy as np
import pytest

from mcsweep.errors import UserInputError
from mcsweep.population import GalaxyModel
from mcsweep.population.galaxy import extinction_arenou as ar
from mcsweep.population.galaxy.density import heliocentric_to_galactocentric
from mcsweep.population.galaxy.extinction import AG_OVER_AV

#: Rounding of the published examples (two decimals).
EXAMPLE_TOL = 0.005


def _table():
    return ar.load_arenou_table()


def test_table_has_199_cells_tiling_every_latitude_band():
    t = _table()
    assert t["alpha"].size == 199
    edges = ar.ARENOU_BAND_EDGES_DEG
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (t["b_min"] == lo) & (t["b_max"] == hi)
        l0, l1 = t["l_min"][sel], t["l_max"][sel]
        assert l0[0] == 0 and l1[-1] == 360
        assert np.array_equal(l0[1:], l1[:-1])          # contiguous, no overlap, no gap
    assert np.sum([((t["b_min"] == lo) & (t["b_max"] == hi)).sum()
                   for lo, hi in zip(edges[:-1], edges[1:])]) == 199


def test_lookup_covers_the_sky_exactly_once():
    # every direction matches exactly one cell by brute force, and the lookup finds it
    rng = np.random.default_rng(25)
    l = np.concatenate([rng.uniform(0, 360, 20000), [0.0, 359.999, 10.0, 29.0, 57.0]])
    b = np.concatenate([np.degrees(np.arcsin(rng.uniform(-1, 1, 20000))), [-90.0, 90.0, 5.0, -5.0, -60.0]])
    t = _table()
    last = t["b_max"] == 90.0
    inside = ((t["l_min"] <= l[:, None]) & (l[:, None] < t["l_max"])
              & (t["b_min"] <= b[:, None]) & ((b[:, None] < t["b_max"]) | (last & (b[:, None] == 90.0))))
    assert np.all(inside.sum(axis=1) == 1)
    assert np.array_equal(ar.cell_index(l, b), np.argmax(inside, axis=1))
    assert np.array_equal(ar.cell_index(l + 360.0, b), ar.cell_index(l, b))


@pytest.mark.parametrize("l, b, d_kpc", [(5.0, 0.0, 0.8), (5.0, 0.0, 3.0), (185.0, -10.0, 0.2),
                                         (185.0, -10.0, 1.0), (20.0, 10.0, 0.3), (300.0, 70.0, 0.05),
                                         (135.0, -40.0, 0.25), (250.0, 50.0, 0.5)])
def test_av_equals_closed_form_of_the_cell(l, b, d_kpc):
    # the cell located by hand from its bounds, then Eq. 5 / 5bis
    t = _table()
    last = t["b_max"] == 90.0
    i = np.flatnonzero((t["l_min"] <= l) & (l < t["l_max"]) & (t["b_min"] <= b)
                       & ((b < t["b_max"]) | (last & (b == 90.0))))[0]
    a, be, g, r0 = t["alpha"][i], t["beta"][i], t["gamma"][i], t["r0_kpc"][i]
    want = a * d_kpc + be * d_kpc ** 2 if d_kpc <= r0 else a * r0 + be * r0 ** 2 + g * (d_kpc - r0)
    assert ar.av_arenou([l], [b], [[d_kpc]])[0, 0] == pytest.approx(max(want, 0.0), abs=1e-12)


def test_published_examples():
    # no distance given: A_V at r0 (gamma = 0 there, so any larger distance)
    assert ar.av_arenou([10.2], [59.0], [[5.0]])[0, 0] == pytest.approx(0.05, abs=EXAMPLE_TOL)
    assert ar.av_arenou([107.05], [-34.93], [[0.14465]])[0, 0] == pytest.approx(0.15, abs=EXAMPLE_TOL)


def test_av_non_decreasing_where_gamma_non_negative():
    # r0 is the parabola's vertex rounded to 1 pc in most cells: allow the rounding
    t = _table()
    assert np.all(t["gamma"] >= 0)
    l = 0.5 * (t["l_min"] + t["l_max"])
    b = 0.5 * (t["b_min"] + t["b_max"])
    r = np.linspace(0.0, 3.0, 3001)
    av = ar.av_arenou(l, b, r[None, :])
    assert np.all(np.diff(av, axis=1) >= -1e-5)


def test_high_latitude_extinction_is_small():
    # |b| > 60 deg: at most 0.10 mag at any distance (the southern cells all end at 0.10)
    t = _table()
    sel = np.abs(t["b_min"] + t["b_max"]) >= 120
    l = 0.5 * (t["l_min"] + t["l_max"])[sel]
    b = 0.5 * (t["b_min"] + t["b_max"])[sel]
    av = ar.av_arenou(l, b, np.array([[10.0]]))[:, 0]
    assert np.all(av <= 0.101) and np.all(av > 0.0)
    assert np.all(av[b < 0] >= 0.097)


def test_validity_limit_is_the_bands_largest_r0():
    t = _table()
    lim = ar.validity_limit_kpc(0.5 * (t["b_min"] + t["b_max"]))
    assert np.all(t["r0_kpc"] <= lim + 0.0005)
    edges = ar.ARENOU_BAND_EDGES_DEG
    for lo, hi in zip(edges[1:-2], edges[2:-1]):       # all bands but the southern cap
        sel = (t["b_min"] == lo) & (t["b_max"] == hi)
        assert t["r0_kpc"][sel].max() == pytest.approx(ar.validity_limit_kpc(0.5 * (lo + hi)), abs=0.0006)


def _sight_line(model, l, b, d_kpc):
    x, y, z = heliocentric_to_galactocentric(np.array([[l]]), np.array([[b]]), d_kpc[None, :],
                                             r0_kpc=model.params["r0_kpc"], z_sun_pc=model.params["z_sun_pc"])
    return x, y, z


def test_join_agg92_inside_the_limit_then_the_disc_increment():
    m = GalaxyModel(extinction_model="arenou1992")
    d = np.geomspace(0.0025, 10.0, 600)
    for l, b in ((5.0, 1.0), (185.0, -10.0), (100.0, 40.0)):
        x, y, z = _sight_line(m, l, b, d)
        a = m.arenou.a_g(np.array([l]), np.array([b]), x, y, z, d)[0]
        disc = m.dust.a_g(x, y, z, d)[0]
        lim = float(ar.validity_limit_kpc(b))
        inside = d <= lim
        agg = np.maximum.accumulate(ar.av_arenou([l], [b], d[None, :])[0]) * AG_OVER_AV
        assert np.allclose(a[inside], agg[inside], atol=1e-12)
        far = d > 1.05 * lim
        a_lim = np.max(ar.av_arenou([l], [b], np.append(d[inside], lim)[None, :])) * AG_OVER_AV
        assert np.allclose(a[far] - a_lim, disc[far] - np.interp(lim, d, disc), atol=1e-9)
        assert np.all(np.diff(a) >= 0)


def test_extinction_model_option_and_errors():
    with pytest.raises(UserInputError, match="extinction_model"):
        GalaxyModel(extinction_model="schlegel")
    assert GalaxyModel(extinction_model="arenou1992", extinction=False).arenou is None
    assert GalaxyModel().params["extinction_model"] == "arenou1992"  # the default since besancon-r03-5


@pytest.fixture(scope="module")
def agg_model():
    # AGG92 alone, without the subgiants of the default
    return GalaxyModel(extinction_model="arenou1992", subgiants=False)


def test_table1_beam_with_agg92(agg_model):
    # the paper's Table 1 beam (458 GUMS stars) within the calibration's 10 % (BEAM_TOL of
    # tests/validation) with AGG92 too
    assert agg_model.expected_count(245.7, 46.5, 1.0, 14.5, 15.5) == pytest.approx(458, rel=0.10)


@pytest.mark.xfail(strict=True, reason="with AGG92 and no subgiants the all-sky counts are 0.88-0.99 x Gaia "
                   "DR3's at G = 4-14 (G = 6-10: 0.88-0.90): the subgiants are missing (the default has "
                   "them since besancon-r03-5; docs/galaxy_model.md)")
def test_all_sky_counts_with_agg92_within_8_percent(agg_model):
    from mcsweep.validation import published_counts as pc
    ratios = pc.count_comparison(agg_model, list(range(4, 14))).ratio_gaia
    assert np.all(np.abs(ratios - 1.0) <= 0.08)
