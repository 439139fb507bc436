"""The galaxy model's compiled draw loops do numpy's arithmetic star by star: the same stars bit
for bit as the numpy passes they replaced (kept here as the references); and a draw whose rows
are made on request (draw_cone) gives the rows of the whole draw."""

import numpy as np
import pandas as pd
import pytest

from mcsweep.population import GalaxyModel
from mcsweep.population.galaxy import colours as C
from mcsweep.population.galaxy import parameters as P
from mcsweep.population.galaxy.draw_kernel import absolute_magnitudes, interp
from mcsweep.population.galaxy.model import PARAMS_R03_5


def _models():
    # the default model's evolved stars from isochrones, and r03-5's Wielen giant bins (whose
    # colour table has the main-sequence part)
    return {"default": GalaxyModel(), "r03_5": GalaxyModel(PARAMS_R03_5)}


@pytest.fixture(scope="module")
def models():
    return _models()


def test_interp_is_numpys_at_nodes_ends_ties_and_nan():
    rng = np.random.default_rng(3)
    xp = np.sort(np.r_[rng.uniform(-5, 5, 40), [0.5, 0.5, 0.5, 2.0, 2.0]])  # ties: flat steps of a cdf
    fp = np.cumsum(rng.uniform(0, 1, xp.size))
    fp[10:14] = fp[10]  # flat values
    x = np.r_[rng.uniform(-6, 6, 5000), xp, [-np.inf, np.inf, np.nan, xp[0], xp[-1]]]
    got = np.array([interp(v, xp, fp) for v in x])
    np.testing.assert_array_equal(got, np.interp(x, xp, fp))
    # inverted (a cdf with flat steps as the abscissa), as the luminosity functions are sampled
    y = rng.uniform(fp[0] - 0.1, fp[-1] + 0.1, 5000)
    np.testing.assert_array_equal(np.array([interp(v, fp, xp) for v in y]), np.interp(y, fp, xp))
    # with a step (the luminosity functions' evenly spaced nodes): numpy's interval too, whether
    # the step is the nodes' spacing, about it, or far from it (uneven nodes, ties)
    even = np.linspace(-12.0, 19.0, 621)
    x_even = np.r_[rng.uniform(-13, 20, 5000), even, even + 1e-15, even - 1e-15, [np.nan, -np.inf, np.inf]]
    for nodes, values, step in [(even, fp[0] + np.sort(rng.uniform(0, 9, even.size)), 0.05),
                                (even, np.sin(even), 0.05 * (1 + 1e-9)), (xp, fp, 0.05), (xp, fp, 3.0)]:
        xs = x_even if nodes is even else x
        got = np.array([interp(v, nodes, values, step) for v in xs])
        np.testing.assert_array_equal(got, np.interp(xs, nodes, values))


def _absolute_magnitudes_numpy(lf, k, mu, a_g, u, g_min, g_max):
    """The numpy passes, component by component."""
    m_g = np.empty(mu.size)
    off = mu + a_g
    for c in np.unique(k):
        sel = k == c
        cdf = lf.cdf[c]
        c_lo = np.interp(g_min - off[sel], lf.mg, cdf)
        c_hi = np.interp(g_max - off[sel], lf.mg, cdf)
        m_g[sel] = np.interp(c_lo + u[sel] * (c_hi - c_lo), cdf, lf.mg)
    return m_g


def _draw_inputs(model, n, seed):
    rng = np.random.default_rng(seed)
    k = rng.integers(0, len(model.components), n)
    mu = rng.uniform(-2.0, 16.0, n)
    a_g = rng.exponential(0.5, n)
    return k, mu, a_g, rng.random(n)


@pytest.mark.parametrize("name", ["default", "r03_5"])
@pytest.mark.parametrize("g_range", [(4.0, 5.0), (12.0, 13.0), (19.0, 20.0)])
def test_absolute_magnitudes_are_the_numpy_passes_bit_for_bit(models, name, g_range):
    model = models[name]
    k, mu, a_g, u = _draw_inputs(model, 50_000, 11)
    got = np.empty(k.size)
    absolute_magnitudes(k, mu, a_g, u, *g_range, model.lf.mg, model.lf.cdf, got)
    np.testing.assert_array_equal(got, _absolute_magnitudes_numpy(model.lf, k, mu, a_g, u, *g_range))


def _intrinsic_numpy(t, k, m_g, u):
    """ColourTable.intrinsic as numpy passes over all stars."""
    i = np.clip(np.searchsorted(t.mg, m_g, side="right") - 1, 0, t.mg.size - 2)
    w = t.density[k, :, i]
    cum = np.cumsum(w, axis=1)
    total = cum[:, -1]
    part = (u[:, None] * total[:, None] >= cum).sum(axis=1)
    part = np.where(total > 0, np.minimum(part, len(C.COLOUR_PARTS) - 1), 0)
    c = np.empty(m_g.size)
    dw = part == 0
    c[dw] = C.dwarf_bp_rp(m_g[dw] + t.shift[k[dw]])
    gi = np.flatnonzero(part == 1)
    level = (u[gi] * total[gi] - cum[gi, 0]) / w[gi, 1]
    nodes = t.giant_mg
    node = np.clip(np.rint((m_g[gi] - nodes[0]) / (nodes[1] - nodes[0])).astype(np.intp), 0, nodes.size - 1)
    x = np.clip(level, 0.0, 1.0) * (C.GIANT_QUANTILE_LEVELS.size - 1)
    j = np.minimum(x.astype(np.intp), C.GIANT_QUANTILE_LEVELS.size - 2)
    f = x - j
    c[gi] = t.giant_q[k[gi], node, j] * (1.0 - f) + t.giant_q[k[gi], node, j + 1] * f
    ms = part == 2
    c[ms] = C.main_sequence_bp_rp(m_g[ms] - P.GIANT_G_MINUS_V)
    c[part == 3] = C.SUBGIANT_BP_RP
    return c, part


@pytest.mark.parametrize("name", ["default", "r03_5"])
def test_intrinsic_colours_are_the_numpy_passes_bit_for_bit(models, name):
    t = models[name].colours
    rng = np.random.default_rng(5)
    n = 200_000
    k = rng.integers(0, t.density.shape[0], n)
    # every part of the table, its edges and nodes, and beyond them
    m_g = np.r_[rng.uniform(t.mg[0] - 1.0, t.mg[-1] + 1.0, n - 2 * t.mg.size), t.mg, t.mg + 1e-13]
    u = rng.random(n)
    colour, part = t.intrinsic(k, m_g, u)
    ref_colour, ref_part = _intrinsic_numpy(t, k, m_g, u)
    np.testing.assert_array_equal(part, ref_part)
    np.testing.assert_array_equal(colour, ref_colour)
    # every part the table holds stars in was drawn
    assert set(np.unique(part).tolist()) == {p for p in range(len(C.COLOUR_PARTS)) if t.density[:, p].any()}


@pytest.mark.parametrize("name, n", [("default", 3000), ("r03_5", 3000), ("default", 20_000)])
def test_a_draw_made_row_by_request_is_the_whole_draw(models, name, n):
    # draw_cone computes the colours of every star and the other columns of the rows asked
    # for (a colour cell's bin): each row as sample_cone's, bit for bit, whatever the number of
    # rows asked for (one row takes other numpy and BLAS routes if computed alone); 20 000 is
    # a sweep cell's draw.
    model = models[name]
    for i, (l, b, g) in enumerate([(0.0, 70.5, 19.0), (120.0, 5.0, 8.0), (280.0, -40.0, 13.0)]):
        args = (l, b, 1.0, g - 0.5, g + 0.5)
        table = model.sample_cone(*args, np.random.default_rng(i), max_stars=n, min_draw=n)
        drawn = model.draw_cone(*args, np.random.default_rng(i), max_stars=n, min_draw=n)
        np.testing.assert_array_equal(drawn.bp_rp, table["bp_rp"].to_numpy())
        assert (drawn.n_in_cone, drawn.expected_count) == (table.attrs["n_in_cone"], table.attrs["expected_count"])
        pd.testing.assert_frame_equal(drawn.stars(), table, check_exact=True)
        rng = np.random.default_rng(i)
        for size in (0, 1, 2, 3, 5, 8, 15, 16, 17, 33, 500):
            rows = np.sort(rng.choice(len(drawn), size, replace=False))
            made = drawn.stars(rows)
            pd.testing.assert_frame_equal(made, table.iloc[rows].reset_index(drop=True), check_exact=True)
            assert made.attrs == table.attrs

        in_bin = drawn.bp_rp > 1.5  # a mask selects the same rows as their positions
        pd.testing.assert_frame_equal(drawn.stars(in_bin), drawn.stars(np.flatnonzero(in_bin)), check_exact=True)


def test_a_draw_in_one_piece_is_the_chunked_draw(models):
    # sample_cone draws more than chunk_stars stars chunk by chunk, draw_cone in one piece
    model = models["default"]
    n = model.chunk_stars + 5000
    args = (0.0, 0.0, 2.0, 12.0, 13.0)
    table = model.sample_cone(*args, np.random.default_rng(1), max_stars=n, min_draw=n)
    drawn = model.draw_cone(*args, np.random.default_rng(1), max_stars=n, min_draw=n)
    assert len(table) == n
    pd.testing.assert_frame_equal(drawn.stars(), table, check_exact=True)


@pytest.mark.parametrize("name", ["default", "r03_5"])
def test_a_draw_without_colours_is_the_draw_with_them_but_bp_rp(models, name):
    # the colour stage draws from a stream of its own: skipping it (the sweep's colour-blind
    # cells) leaves every other column as it was, bit for bit, over more than one chunk too
    model = models[name]
    n = model.chunk_stars + 3000
    for i, (l, b, g) in enumerate([(0.0, 70.5, 19.0), (120.0, 5.0, 8.0)]):
        args = (l, b, 1.0, g - 0.5, g + 0.5)
        table = model.sample_cone(*args, np.random.default_rng(i), max_stars=n, min_draw=n)
        plain = model.sample_cone(*args, np.random.default_rng(i), max_stars=n, min_draw=n, colours=False)
        assert plain["bp_rp"].isna().all() and table["bp_rp"].notna().all()
        pd.testing.assert_frame_equal(plain.drop(columns="bp_rp"), table.drop(columns="bp_rp"), check_exact=True)
        assert plain.attrs == table.attrs


@pytest.mark.parametrize("name", ["default", "r03_5"])
def test_rows_of_several_draws_in_one_pass_are_their_tables_concatenated(models, name):
    # a colour cell takes its bin's rows from several batches of one cone and G range:
    # ConeDraw.stars_of makes them in one pass, the values and attrs of the batches' tables
    # concatenated, bit for bit, whatever the parts' sizes (empty, fewer than _MIN_ROWS, many)
    from mcsweep.population.galaxy.model import ConeDraw

    model = models[name]
    args = (120.0, 5.0, 1.0, 13.5, 14.5)
    draws = [model.draw_cone(*args, np.random.default_rng(i), max_stars=3000, min_draw=3000) for i in range(4)]
    rng = np.random.default_rng(9)
    for sizes in [(500, 3, 0, 1200), (1, 2, 3, 4), (0, 2000, 7, 0), (3000, 3000, 3000, 3000), (40,)]:
        parts = [(d, np.sort(rng.choice(len(d), size, replace=False))) for d, size in zip(draws, sizes)]
        want = pd.concat([d.stars(rows) for d, rows in parts], ignore_index=True)
        got = ConeDraw.stars_of(parts)
        pd.testing.assert_frame_equal(got, want, check_exact=True)
        assert got.attrs == want.attrs
    # masks are taken as stars() takes them; a draw of another query is not finished with these
    mask = draws[0].bp_rp > 1.0
    other = model.draw_cone(0.0, 60.0, 1.0, 13.5, 14.5, np.random.default_rng(5), max_stars=500, min_draw=500)
    parts = [(draws[0], mask), (other, np.arange(200)), (draws[1], None)]
    want = pd.concat([d.stars(rows) for d, rows in parts], ignore_index=True)
    pd.testing.assert_frame_equal(ConeDraw.stars_of(parts), want, check_exact=True)
    # one query's draws with equal attrs keep them, as pd.concat does
    same = [(draws[2], np.arange(100)), (draws[2], np.arange(100, 300))]
    assert ConeDraw.stars_of(same).attrs == draws[2].stars([0]).attrs
