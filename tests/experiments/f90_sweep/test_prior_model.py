"""The sweep's prior models (``prior_model``): the colour axis and the mean-centred prior,
against closed forms (a Gaussian truth, the linearity of Eqs. 11-13, known coefficients) and
against the colour-blind sweep they must leave bit for bit."""

import math
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from astropy import units as u
from astropy.coordinates import SkyCoord

from mcsweep.astrometry.solve import solve_with_prior
from mcsweep.command.provenance import config_hash
from mcsweep.population.galaxy.model import PARAMS_R03_5
from mcsweep.command.validate import compose_config, to_config
from mcsweep.experiments.f90_sweep.cells import Cell, enumerate_cells, sky_directions
from mcsweep.experiments.f90_sweep.colour_fit import colour_tables
from mcsweep.experiments.f90_sweep.conf import SkyConf
from mcsweep.experiments.f90_sweep.fit import PAPER_COEFFICIENTS, POLY_DEGREES, evaluate_formula
from mcsweep.experiments.f90_sweep.pencil_beam import (
    COLOUR_MIN_STARS, cell_mean, cell_stars, run_cell)
from mcsweep.experiments.f90_sweep.runner import build_settings, direction_transits
from mcsweep.population import GalaxyModel

P = 0.9
N_STARS = 4000
# Binomial scatter of a fraction P on N_STARS stars: 3 sigma = 0.014.
FRACTION_TOL = 3 * math.sqrt(P * (1 - P) / N_STARS)
#: The toy's truth: mean parallax and proper motion (ICRS at the beam centre), widths.
MEAN_PLX, MEAN_PMRA, MEAN_PMDEC, SIGMA_PLX, RATIO_R = 5.0, 20.0, -12.0, 1.0, 10.0
#: 4 standard errors of a mean of N_STARS draws of a unit-sigma variable.
MEAN_TOL = 4 / math.sqrt(N_STARS)
#: Rotations of mas/yr-sized proper motions between frames agree with astropy to rounding.
ROTATION_TOL_MASYR = 1e-9
#: Two exact solutions of the same 5 x 5 systems (condition ~1e3): rounding only.
SOLVE_TOL = 1e-9
#: Least squares on noise-free cells reproduce the coefficients to rounding.
FIT_TOL = 1e-8
#: Radius over which the toy's stars are spread (Table 1's beam).
BEAM_DEG = 1.0


class OffsetGaussianSource:
    """Stars at the beam centre whose parallax and proper motion are Gaussian about a non-zero
    mean: a prior centred on that mean with the truth's widths is the exact posterior of
    Eqs. 9-13, so the fraction inside the P ellipse is P in expectation (Sect. 2.3-2.4)."""

    draws_from_density = True

    def __init__(self, mean=(MEAN_PLX, MEAN_PMRA, MEAN_PMDEC), sigma=SIGMA_PLX, colours=None):
        self.mean, self.sigma, self.colours = mean, sigma, colours

    def expected_count(self, l_deg, b_deg, radius_deg, g_min, g_max):
        return float(N_STARS)

    def sample_cone(self, l_deg, b_deg, radius_deg, g_min, g_max, rng, max_stars=None, min_draw=None):
        n = N_STARS
        plx = rng.normal(self.mean[0], self.sigma, n)
        pm = rng.normal(0, RATIO_R * self.sigma, (2, n)) + np.array(self.mean[1:])[:, None]
        # Spread over the beam, so a mean over the stars rotates each star's own proper motion.
        centre = SkyCoord(l=l_deg * u.deg, b=b_deg * u.deg, frame="galactic")
        c = centre.directional_offset_by(rng.uniform(0, 360, n) * u.deg,
                                         BEAM_DEG * np.sqrt(rng.uniform(0, 1, n)) * u.deg).icrs
        gal = c.galactic
        df = pd.DataFrame({"ra": c.ra.deg, "dec": c.dec.deg, "l": gal.l.deg, "b": gal.b.deg, "parallax": plx,
                           "pmra": pm[0], "pmdec": pm[1], "phot_g_mean_mag": rng.uniform(g_min, g_max, n),
                           "distance_pc": np.inf, "population": "test"})
        if self.colours is not None:
            df["bp_rp"] = rng.choice(self.colours, n)
        df.attrs["n_in_cone"] = n
        return df


@pytest.fixture(scope="module")
def beam():
    d = sky_directions(SkyConf(name="t1", kind="list", frame="icrs", directions=[[157.5, 0.0]]))[0]
    config = to_config(compose_config(["sky=single", "magnitudes=g15", f"cell.max_stars={N_STARS}",
                                       f"cell.min_stars={N_STARS}", "cell.n_bootstrap=0"]))
    return config, d, direction_transits(config, [d])[d.index]


def _settings(config, **kw):
    import dataclasses

    return dataclasses.replace(build_settings(config), **kw)


def test_cell_mean_is_the_population_mean_in_closed_form(beam):
    config, d, _ = beam
    stars = OffsetGaussianSource().sample_cone(d.l_deg, d.b_deg, 1.0, 14.5, 15.5, np.random.default_rng(3))
    m = cell_mean(stars, d)
    assert m["mean_parallax_mas"] == pytest.approx(MEAN_PLX, abs=MEAN_TOL * SIGMA_PLX)
    assert m["mean_pmra_masyr"] == pytest.approx(MEAN_PMRA, abs=MEAN_TOL * RATIO_R * SIGMA_PLX)
    assert m["mean_pmdec_masyr"] == pytest.approx(MEAN_PMDEC, abs=MEAN_TOL * RATIO_R * SIGMA_PLX)
    # The galactic components are the mean of astropy's rotation of each star's proper motion.
    ref = SkyCoord(ra=stars["ra"].to_numpy() * u.deg, dec=stars["dec"].to_numpy() * u.deg,
                   pm_ra_cosdec=stars["pmra"].to_numpy() * u.mas / u.yr,
                   pm_dec=stars["pmdec"].to_numpy() * u.mas / u.yr).galactic
    assert m["mean_pml_masyr"] == pytest.approx(ref.pm_l_cosb.to_value(u.mas / u.yr).mean(), abs=ROTATION_TOL_MASYR)
    assert m["mean_pmb_masyr"] == pytest.approx(ref.pm_b.to_value(u.mas / u.yr).mean(), abs=ROTATION_TOL_MASYR)
    # ... given in ICRS at the beam centre (astropy's rotation back).
    back = SkyCoord(l=d.l_deg * u.deg, b=d.b_deg * u.deg, pm_l_cosb=m["mean_pml_masyr"] * u.mas / u.yr,
                    pm_b=m["mean_pmb_masyr"] * u.mas / u.yr, frame="galactic").icrs
    assert m["mean_pmra_masyr"] == pytest.approx(back.pm_ra_cosdec.to_value(u.mas / u.yr), abs=ROTATION_TOL_MASYR)


def test_a_shifted_truth_gives_the_errors_of_a_prior_centred_on_the_mean():
    # Eqs. 11-13 with N_p and a centre m: x = (N + N_p)^-1 (b + N_p m); the errors equal those
    # of the zero-centred prior for the truth x - m, which the sweep solves.
    rng = np.random.default_rng(5)
    n = 50
    a = rng.normal(size=(n, 8, 5))
    n0 = np.einsum("nki,nkj->nij", a, a)
    truth = np.column_stack([np.zeros((n, 2)), rng.normal([5, 20, -12], [1, 10, 10], (n, 3))])
    noise = np.einsum("nki,nk->ni", a, rng.normal(size=(n, 8)))
    m = np.array([0, 0, 5.0, 20.0, -12.0])
    sigma = 1.3
    w = np.diag([0, 0, sigma**-2, (RATIO_R * sigma) ** -2, (RATIO_R * sigma) ** -2])
    direct = np.linalg.solve(n0 + w, (np.einsum("nij,nj->ni", n0, truth) + noise + w @ m)[..., None])[..., 0]
    shifted = solve_with_prior(n0, np.einsum("nij,nj->ni", n0, truth - m) + noise, sigma, RATIO_R).x
    np.testing.assert_allclose(shifted, direct - m, rtol=SOLVE_TOL, atol=SOLVE_TOL)


def test_the_mean_centred_prior_is_honest_where_the_zero_centred_is_not(beam):
    config, d, transits = beam
    cell = Cell(d, 14.5, 15.5)
    source = OffsetGaussianSource()
    grid_row = lambda t: t[(t["case"] == "two") & ~t["at_f90"] & np.isclose(t["sigma_prior_mas"], SIGMA_PLX)]
    centred, _ = run_cell(cell, transits, source, _settings(config, mean=True))
    zero, _ = run_cell(cell, transits, source, _settings(config, mean=False))
    assert grid_row(centred)["fraction_inside"].iloc[0] == pytest.approx(P, abs=FRACTION_TOL)
    # A 5 mas offset against a 1 mas prior: the zero-centred ellipses miss most errors.
    assert grid_row(zero)["fraction_inside"].iloc[0] < 0.5
    # The prior's centre is estimated from an independent draw of the cell (stream 3).
    assert centred["mean_parallax_mas"].iloc[0] == pytest.approx(MEAN_PLX, abs=MEAN_TOL)
    # Quasars (zero truth) are 5 sigma from that centre: a mean-centred prior misplaces them.
    assert centred["quasar_fraction_inside"].iloc[0] < 0.5


def test_quasars_at_a_zero_mean_are_never_under_covered(beam):
    # With a population centred on zero, the centre is ~0 and quasars sit at it: their
    # fraction inside is at least P (truth at the prior's centre, Loewner order C N0 C <= C).
    config, d, transits = beam
    table, _ = run_cell(Cell(d, 14.5, 15.5), transits, OffsetGaussianSource(mean=(0, 0, 0)),
                        _settings(config, mean=True))
    assert table["quasar_fraction_inside"].iloc[0] > P - FRACTION_TOL
    assert table["quasar_n_valid"].iloc[0] == N_STARS


@pytest.fixture(scope="module")
def galaxy_beam():
    d = sky_directions(SkyConf(name="t1", kind="list", frame="icrs", directions=[[157.5, 0.0]]))[0]
    config = to_config(compose_config(["sky=single", "magnitudes=g15", "cell.max_stars=1500", "cell.min_stars=1500",
                                       "cell.n_bootstrap=10", "prior_grid.n=13"]))
    return config, d, direction_transits(config, [d])[d.index]


def test_a_colour_blind_cell_is_the_same_bits_with_the_colour_axis_on(galaxy_beam):
    config, d, transits = galaxy_beam
    cell = Cell(d, 14.5, 15.5)
    off, _ = run_cell(cell, transits, GalaxyModel(), build_settings(config))
    on, _ = run_cell(cell, transits, GalaxyModel(), _settings(config, colour_axis=True))
    assert list(on.columns[:len(off.columns)]) == list(off.columns)
    pd.testing.assert_frame_equal(on[off.columns], off, check_exact=True)
    assert on["bp_rp_min"].isna().all() and on["bp_rp_max"].isna().all()


def test_a_colour_cell_holds_the_stars_of_its_bin(galaxy_beam):
    config, d, _ = galaxy_beam
    s = build_settings(config)
    blind, colour = Cell(d, 14.5, 15.5), Cell(d, 14.5, 15.5, 0.56, 1.23)
    assert colour.cell_id.startswith(blind.cell_id + "_c") and colour.key[:4] == blind.key
    stars = cell_stars(colour, GalaxyModel(), s, 1.0, 0)
    c = stars["bp_rp"].to_numpy()
    assert len(stars) == s.min_stars and np.all((c >= 0.56) & (c < 1.23))
    again = cell_stars(colour, GalaxyModel(), s, 1.0, 0)
    pd.testing.assert_frame_equal(stars, again, check_exact=True)  # seeded by the cell's content


def test_a_rare_colour_is_flagged_not_fitted(beam):
    config, d, transits = beam
    # One star in 10 000 is blue: 10 batches of N_STARS give ~4, far below COLOUR_MIN_STARS.
    source = OffsetGaussianSource(colours=np.r_[np.full(9999, 1.0), 0.0])
    table, _ = run_cell(Cell(d, 14.5, 15.5, -1.0, 0.56), transits, source, _settings(config, colour_axis=True))
    assert table["f90_flag"].iloc[0] == "few_stars" and table["n_stars"].iloc[0] < COLOUR_MIN_STARS
    assert table["fraction_inside"].isna().all()


def test_the_per_colour_fit_recovers_known_coefficients():
    # Cells whose sigma_F90 follows Eqs. 14-17 exactly, with other coefficients per colour bin:
    # the per-bin fit returns them, and its residual RMS is zero where the colour-blind one is not.
    dirs = sky_directions(SkyConf(name="h", kind="healpix", nside=2))
    g_edges = np.arange(6.0, 21.0)
    truth = {(-1.0, 0.56): PAPER_COEFFICIENTS,
             (0.56, 6.0): {k: tuple(np.asarray(v) + 0.2 * (k == "s0") * np.eye(1, len(v))[0])
                           for k, v in PAPER_COEFFICIENTS.items()}}
    rows = []
    for (c0, c1), coef in [((np.nan, np.nan), PAPER_COEFFICIENTS), *truth.items()]:
        for d in dirs:
            for g0, g1 in zip(g_edges[:-1], g_edges[1:]):
                rows.append(dict(cell_id=f"{d.index}_{g0}_{c0}", l_deg=d.l_deg, b_deg=d.b_deg, g_min=g0, g_max=g1,
                                 bp_rp_min=c0, bp_rp_max=c1, f90_flag="ok",
                                 sigma_f90_mas=float(evaluate_formula(coef, d.l_deg, d.b_deg, (g0 + g1) / 2))))
    f90 = pd.DataFrame(rows)
    tables = colour_tables(f90, dict(PAPER_COEFFICIENTS))
    coef = tables["colour_coefficients.csv"]
    for (c0, _), want in truth.items():
        got = coef[coef["bp_rp_min"] == c0].set_index("term")["fitted"]
        for name, deg in POLY_DEGREES.items():
            np.testing.assert_allclose([got[f"{name}_c{k}"] for k in range(deg + 1)], want[name], atol=FIT_TOL)
    forms = tables["colour_fit_forms.csv"].set_index(["form", "colour_bin"])["rms_dex"]
    assert forms["per_bin", "all"] < FIT_TOL
    # The prior's form, Eq. 14 per G bin: each bin's terms are the polynomials at its centre.
    terms = tables["colour_terms.csv"]
    for (c0, _), want in truth.items():
        t = terms[terms["bp_rp_min"] == c0].sort_values("g")
        for name in ("s0", "s1", "s2"):
            np.testing.assert_allclose(t[name], np.polynomial.polynomial.polyval(t["g"], want[name]), atol=FIT_TOL)
    assert forms["per_bin_g", "all"] < FIT_TOL
    cells = tables["f90_colour_cells.csv"]
    np.testing.assert_allclose(cells["fitted_sigma_f90_mas"], cells["sigma_f90_mas"], rtol=FIT_TOL)
    assert forms["colour_blind", "0.56..6"] == pytest.approx(0.2, abs=FIT_TOL)  # the s0 offset
    assert forms["offset", "0.56..6"] < FIT_TOL  # a constant offset is that form exactly


def test_prior_models_hash_apart_and_the_default_as_before():
    default, colour, mean = _raw([]), _raw(["prior_model=colour"]), _raw(["prior_model=colour_mean"])
    assert config_hash(default) == config_hash(_raw(["prior_model=direction_g"]))
    assert len({config_hash(default), config_hash(colour), config_hash(mean)}) == 3
    # The default sweep's hash pinned at 66652ca, before the group existed, under that day's
    # galaxy model (besancon-r03-5)
    r03_5 = [f"population.params.{k}={v}" for k, v in PARAMS_R03_5.items()]
    assert config_hash(_raw(r03_5)) == "285a027a54185cfd"
    assert config_hash(_raw(["prior_model=direction_g"] + r03_5)) == "285a027a54185cfd"


def _raw(over):
    from omegaconf import OmegaConf

    return OmegaConf.to_container(compose_config(over), resolve=True)


def test_colour_cells_follow_each_direction_and_g_bin():
    config = to_config(compose_config(["prior_model=colour", "sky=single", "magnitudes=g15"]))
    cells = enumerate_cells(config.sky, config.magnitudes, config.prior_model.colour_edges)
    assert [c.bp_rp_min for c in cells] == [None, -1.0, 0.56, 1.23, 2.0]
    assert len({c.cell_id for c in cells}) == 5


def test_a_catalogue_has_no_colours_for_the_colour_axis(tmp_path):
    path = tmp_path / "cat.csv"
    pd.DataFrame({"ra": [1.0], "dec": [2.0], "parallax": [1.0], "pmra": [0.0], "pmdec": [0.0],
                  "phot_g_mean_mag": [15.0]}).to_csv(path, index=False)
    r = subprocess.run([sys.executable, "-c", "from mcsweep.cli import main; main()", "prior_model=colour",
                        "population=catalogue", f"population.path={path}", "sky=single", "magnitudes=g15",
                        f"hydra.run.dir={tmp_path / 'run'}"], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "prior_model.colour_edges" in lines[0] and "population=galaxy_model" in lines[0]
    assert not (tmp_path / "run" / "cells").exists()


def test_colour_cells_are_the_same_bits_with_their_batches_shared_or_not(galaxy_beam):
    # One task runs a direction x G bin's colour cells with one set of batches; each cell
    # alone draws the same batches (content-keyed), so the tables are identical, in any order.
    config, d, transits = galaxy_beam
    s = _settings(config, colour_axis=True)
    cells = [Cell(d, 14.5, 15.5, c0, c1) for c0, c1 in ((-1.0, 0.56), (0.56, 1.23), (1.23, 6.0))]
    alone = [run_cell(c, transits, GalaxyModel(), s)[0] for c in cells]
    draws: dict = {}
    shared = [run_cell(c, transits, GalaxyModel(), s, draws=draws)[0] for c in reversed(cells)][::-1]
    for a, b in zip(alone, shared):
        pd.testing.assert_frame_equal(a, b, check_exact=True)
    assert len(draws) == 1


@pytest.mark.parametrize("model", [{}, {"colour_axis": True}, {"colour_axis": True, "mean": True}])
def test_the_arrow_table_a_worker_writes_is_pandas_conversion_of_the_cell(galaxy_beam, model):
    # The sweep's workers build a cell's table as Arrow with the schema of the first cell they
    # converted from pandas; every later cell (flagged ones too: a colour bin without stars)
    # must be what pandas would have made of it, types and pandas metadata included.
    import pyarrow as pa

    config, d, transits = galaxy_beam
    s = _settings(config, **model)
    bins = ((None, None), (0.56, 1.23), (5.9, 6.0)) if model else ((None, None),)
    cells = [Cell(d, g, g + 1.0, c0, c1) for g in (13.5, 14.5) for c0, c1 in bins]
    for cell in cells:
        arrow, _ = run_cell(cell, transits, GalaxyModel(), s, arrow=True)
        frame, _ = run_cell(cell, transits, GalaxyModel(), s)
        assert arrow.equals(pa.Table.from_pandas(frame, preserve_index=False), check_metadata=True), cell.cell_id

