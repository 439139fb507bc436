"""The whole-sky secondary solution of paper Sect. 4.1 (Table 2), reduced in size."""

import dataclasses
import math
import re
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from mcsweep.errors import UserInputError
from mcsweep.experiments.global_solution import classes as C
from mcsweep.experiments.secondary import CHUNKS_DIR
from mcsweep.experiments.secondary import experiment as S
from mcsweep.experiments.global_solution.settings import load_f90_coefficients
from mcsweep.experiments.global_solution.table import SUBSETS
from mcsweep.experiments.secondary.table import (NO_PRIOR_COLUMNS, PAPER_TABLE2, PRIORS, SOLUTION_COLUMNS,
                                                 TABLE2_COLUMNS, paper_value)
from mcsweep.population import CatalogueSource, GalaxyModel
from mcsweep.prior import PAPER_COEFFICIENTS, sigma_f90
from mcsweep.command.provenance import Provenance
from mcsweep.experiments.registry import get as experiment
from mcsweep.command.validate import compose_config, to_config

BIN = Path(sys.executable).parent
CLASS_SIZE = 3000  # stars per magnitude class of the reduced run
REDUCED = ["experiment=secondary", f"experiment.secondary.class_size={CLASS_SIZE}", "execution.progress=false"]
#: Binomial standard deviations allowed for a Monte Carlo fraction against its expectation.
N_SIGMA = 4.0


def _config(overrides):
    cfg = compose_config([*REDUCED, *overrides])
    return to_config(cfg), OmegaConf.to_container(cfg, resolve=True)


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    """The reduced run through the CLI: 2 loky workers, default chunk_stars (one chunk per class)."""
    out = tmp_path_factory.mktemp("secondary") / "run"
    r = subprocess.run([str(BIN / "mcsweep"), f"hydra.run.dir={out}", *REDUCED, "execution.n_jobs=2"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def settings():
    return S.build_settings(_config([])[0])


# ----------------------------------------------------------------------------- end to end
@pytest.mark.slow
def test_reduced_run_through_cli_writes_table2(cli_run):
    table = pd.read_csv(cli_run / "table2.csv")
    assert tuple(table.columns) == TABLE2_COLUMNS
    assert len(table) == 2 * 5 * 3
    assert list(dict.fromkeys(table["subset"])) == ["<=4", ">4"]
    assert list(dict.fromkeys(table["prior"])) == list(PRIORS)
    assert sorted(set(table["g_class"])) == [11, 15, 19]
    summary = pd.read_csv(cli_run / "secondary_summary.csv").set_index("g_class")
    for g, part in table.groupby("g_class"):
        n = part.drop_duplicates("subset")["n_stars"].sum()
        assert n + summary.at[g, "n_no_transit"] == CLASS_SIZE == summary.at[g, "n_stars"]
    # The paper's columns hold its Table 2 (fractions in per cent there).
    for r in table.itertuples():
        i = (11, 15, 19).index(r.g_class)
        frac_pct, p90 = PAPER_TABLE2[(r.subset, r.prior)]
        assert r.paper_fraction_inside == pytest.approx(frac_pct[i] / 100, abs=1e-12)
        assert r.paper_p90_error_mas == p90[i]
    # 95 % dilution of ~90 five-year transits leaves ~4.4 per star (Sect. 4.1: "~4.4").
    assert summary["fraction_retained"].between(0.045, 0.055).all()
    assert summary["mean_fov_retained"].between(3.9, 4.9).all()
    md = (cli_run / "table2.md").read_text()
    assert "| sigma_F90 |" in md and "(90.1)" in md and "(33)" in md
    no_prior = pd.read_csv(cli_run / "no_prior.csv")
    assert tuple(no_prior.columns) == NO_PRIOR_COLUMNS
    # Sect. 4.1: without prior "it was not possible to determine a unique solution for all stars".
    assert (no_prior[no_prior["subset"] == "<=4"]["n_unsolved"] > 0).all()
    report = (cli_run / "report.md").read_text()
    assert "Table 2" in report and "| sigma_F90 |" in report and "Provenance" in report


@pytest.mark.slow
def test_f90_prior_is_calibrated_and_two_parameter_solution_is_not(cli_run):
    t = pd.read_csv(cli_run / "table2.csv")
    f90, none = t[t["prior"] == "F90"], t[t["prior"] == "none"]
    # Paper Table 2: 89.4-91.4 % at sigma_F90 in every cell; 0.3-13.5 % for two parameters.
    assert f90["fraction_inside"].between(0.85, 0.95).all(), f90
    assert (none["fraction_inside"] < 0.5).all(), none
    # "The use of this prior ... also reduces the actual errors compared with a two-parameter
    # solution" (Sect. 4.1).
    assert (f90["p90_error_mas"].to_numpy() < none["p90_error_mas"].to_numpy()).all()


def _per_star(run_dir: Path) -> pd.DataFrame:
    parts = sorted((run_dir / CHUNKS_DIR).glob("class*.parquet"))
    return pd.concat([pd.read_parquet(p).assign(g=p.name[5:9]) for p in parts], ignore_index=True)


@pytest.mark.slow
def test_same_results_whatever_the_chunk_size_and_n_jobs(cli_run, tmp_path):
    # In process, sequential, 1024-star chunks (3 per class) against the CLI's 2 workers
    # and one chunk per class.
    config, raw = _config(["execution.chunk_stars=1000", "execution.n_jobs=1"])
    out = tmp_path / "chunked"
    experiment("secondary").run(config, raw, out, Provenance(out, raw, kind="secondary"))
    assert len(list((out / CHUNKS_DIR).glob("class*.parquet"))) == 3 * 3
    for name in ("table2.csv", "no_prior.csv", "secondary_summary.csv", "table2.md"):
        assert (out / name).read_bytes() == (cli_run / name).read_bytes(), name
    pd.testing.assert_frame_equal(_per_star(out), _per_star(cli_run), check_exact=True)


# ----------------------------------------------------------------------------- chunks
def _sky_stars(n, rng, g=15.0, astrometry=True):
    ra = rng.uniform(0.0, 360.0, n)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    from astropy.coordinates import SkyCoord

    gal = SkyCoord(ra=ra, dec=dec, unit="deg").galactic
    scale = 1.0 if astrometry else 0.0
    return {"ra": ra, "dec": dec, "l": gal.l.deg, "b": gal.b.deg, "phot_g_mean_mag": np.full(n, g),
            "parallax": scale * rng.uniform(0.2, 3.0, n), "pmra": scale * rng.normal(0, 10, n),
            "pmdec": scale * rng.normal(0, 10, n)}


def test_chunk_results_do_not_depend_on_how_stars_are_split(settings, rng):
    stars = _sky_stars(2500, rng)
    whole = S.solve_chunk(settings, 15.0, 0, stars)
    parts = [S.solve_chunk(settings, 15.0, lo, {k: v[lo:lo + 1024] for k, v in stars.items()})
             for lo in (0, 1024, 2048)]
    pd.testing.assert_frame_equal(pd.concat(parts, ignore_index=True), whole, check_exact=True)
    with pytest.raises(ValueError, match="multiple of SECONDARY_NOISE_BLOCK_STARS"):
        S.solve_chunk(settings, 15.0, 1000, stars)


def _coverage(res, stem):
    inside = res[f"inside_{stem}"].to_numpy()
    ok = inside >= 0
    return float(np.mean(inside[ok] == 1)), int(ok.sum())


def test_unbiased_solutions_have_coverage_P_and_priors_at_least_P_for_zero_truth(settings, rng):
    # x_true = 0: the position-only and the no-prior solutions are unbiased with exact
    # covariances, so each star is inside its P ellipse with probability P. A prior centred
    # on the truth shrinks the actual errors below the posterior covariance
    # (cov(error) = C N0 C <= C, Eq. 13), so its coverage is at least P.
    res = S.solve_chunk(settings, 15.0, 0, _sky_stars(2048, rng, astrometry=False))
    p = settings.confidence
    for name, stem in SOLUTION_COLUMNS.items():
        frac, n = _coverage(res, stem)
        tol = N_SIGMA * math.sqrt(p * (1 - p) / n)
        if name in ("none", "5p"):
            assert abs(frac - p) < tol, name
        else:
            assert frac > p - tol, name
    # Dilution keeps each transit with probability 1 - 0.95.
    kept, total = res["n_fov"].sum(), res["n_transits"].sum()
    q = 1.0 - settings.dilution
    assert abs(kept / total - q) < N_SIGMA * math.sqrt(q * (1 - q) / total)
    # Every star with a transit gets every prior (and the position-only) solution.
    seen = res["n_fov"].to_numpy() > 0
    for stem in ("none", "tight", "f90", "f90x10", "loose"):
        assert (res[f"inside_{stem}"].to_numpy()[seen] >= 0).all()
        assert (res[f"inside_{stem}"].to_numpy()[~seen] == -1).all()


def test_truth_drawn_from_the_f90_prior_gives_coverage_P_at_f90(settings, rng):
    # Bayes (Eqs. 11-13): if parallax ~ N(0, sigma_F90^2) and proper motion ~ N(0, (R sigma_F90)^2),
    # the posterior is the exact distribution of the truth given the data, so the P ellipse of
    # the sigma_F90 solution holds the truth with probability P; so does the no-prior solution's.
    stars = _sky_stars(2048, rng, astrometry=False)
    sig = settings.sigma_f90_mas(stars["l"], stars["b"], stars["phot_g_mean_mag"])
    stars["parallax"] = sig * rng.standard_normal(sig.size)
    stars["pmra"] = settings.ratio_R * sig * rng.standard_normal(sig.size)
    stars["pmdec"] = settings.ratio_R * sig * rng.standard_normal(sig.size)
    res = S.solve_chunk(settings, 15.0, 0, stars)
    p = settings.confidence
    for stem in ("f90", "no_prior"):
        frac, n = _coverage(res, stem)
        assert abs(frac - p) < N_SIGMA * math.sqrt(p * (1 - p) / n), stem


# ----------------------------------------------------------------------------- the stars
def test_class_is_the_brightest_stars_fainter_than_g0_in_a_catalogue(tmp_path, rng):
    n = 400
    g = np.round(rng.uniform(8.0, 20.0, n), 3)
    d = _sky_stars(n, rng)
    cat = pd.DataFrame({"ra": d["ra"], "dec": d["dec"], "parallax": d["parallax"], "pmra": d["pmra"],
                        "pmdec": d["pmdec"], "phot_g_mean_mag": g})
    path = tmp_path / "stars.csv"
    cat.to_csv(path, index=False)
    src = CatalogueSource(path)
    got = C.select_class_stars(src, 15.0, 50, np.random.default_rng(0))
    expect = np.sort(g[g >= 15.0])[:50]
    assert np.array_equal(np.sort(got["phot_g_mean_mag"].to_numpy()), expect)
    # Kept in catalogue order.
    pos = [int(np.flatnonzero(g == v)[0]) for v in got["phot_g_mean_mag"]]
    assert pos == sorted(pos)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        few = C.select_class_stars(src, 19.5, 10_000, np.random.default_rng(0))
    assert len(few) == int((g >= 19.5).sum()) and any("fewer than" in str(x.message) for x in w)


def test_class_from_the_galaxy_model_matches_its_expected_counts():
    model, n, g0 = GalaxyModel(), 2000, 15.0
    stars = C.select_class_stars(model, g0, n, np.random.default_rng(1))
    g = stars["phot_g_mean_mag"].to_numpy()
    assert len(stars) == n and g.min() >= g0
    # The n-th brightest star of a Poisson sky: expected count to its G is n +- sqrt(n).
    assert abs(model.expected_count(0, 90, 180, g0, g.max()) - n) < N_SIGMA * math.sqrt(n)
    assert model.expected_count(0, 90, 180, g0, stars.attrs["g_upper"]) >= n + C.MARGIN_SIGMAS * math.sqrt(n)


def test_faint_limit_on_closed_forms():
    def power(g):  # count(g) = 1e6 (g - 10)^2 -> exact G1 = 10 + sqrt(target / 1e6)
        return 1e6 * (g - 10.0) ** 2

    g1 = C.faint_limit(power, 10.0, 21.0, 5e5)
    assert 5e5 <= power(g1) <= 1.05 * 5e5
    assert C.faint_limit(power, 10.0, 10.5, 5e5) == 10.5  # not enough stars: the limit itself
    steps = np.sort(np.random.default_rng(3).uniform(10.0, 21.0, 1000))  # a catalogue's step function
    count = lambda g: float(np.searchsorted(steps, g, side="left"))  # noqa: E731
    assert count(C.faint_limit(count, 10.0, 21.0, 300)) >= 300


# ----------------------------------------------------------------------------- data and config
TABLE2_SOURCE = Path(__file__).parent / "data" / "table2_source.tex"


def _table2_from_latex():
    # Independent of the transcription: the rows of the paper's LaTeX tabular, in order
    # (5 priors for the <= 4 subset, then 5 for > 4), numbers read with a regex.
    rows = [line for line in TABLE2_SOURCE.read_text().splitlines()
            if line.count("&") == 6 and "multicolumn" not in line and "$G" not in line]
    out = {}
    for i, line in enumerate(rows):
        cells = line.rstrip("\\ ").split("&")[1:]
        nums = [float(re.sub(r"[^0-9.]", "", c)) for c in cells]
        out[(SUBSETS[i // 5], PRIORS[i % 5])] = (tuple(nums[:3]), tuple(nums[3:]))
    return out


def test_paper_table2_transcription_matches_the_latex_source():
    assert _table2_from_latex() == dict(PAPER_TABLE2)
    assert paper_value("<=4", "none", 11, 0.9) == (0.005, 33.0)
    assert math.isnan(paper_value("<=4", "F90", 15, 0.8)[0])  # other P: fractions not comparable
    assert all(math.isnan(v) for v in paper_value("<=4", "F90", 12, 0.9))


def test_fitted_formula_from_a_sweep_coefficients_file(tmp_path):
    rows = [(f"{k}_c{i}", c) for k, cs in PAPER_COEFFICIENTS.items() for i, c in enumerate(cs)]
    pd.DataFrame(rows, columns=["term", "fitted"]).assign(paper=0.0).to_csv(tmp_path / "coefficients.csv",
                                                                           index=False)
    coeffs = load_f90_coefficients(str(tmp_path))
    s = S.SecondarySettings(seed=0, start_jd=0, end_jd=1, law=None, dilution=0.95, noise=None,
                            confidence=0.9, ratio_R=10.0, f90_coefficients=coeffs)
    l, b, g = np.array([0.0, 120.0]), np.array([5.0, -60.0]), np.array([11.0, 20.5])
    np.testing.assert_allclose(s.sigma_f90_mas(l, b, g), sigma_f90(l, b, g), rtol=1e-14)
    assert load_f90_coefficients("paper") is None
    with pytest.raises(UserInputError, match="f90_formula"):
        load_f90_coefficients(str(tmp_path / "missing.csv"))
    pd.DataFrame({"term": ["s0_c0"], "fitted": [1.0]}).to_csv(tmp_path / "short.csv", index=False)
    with pytest.raises(UserInputError, match="f90_formula"):
        load_f90_coefficients(str(tmp_path / "short.csv"))


@pytest.mark.parametrize("override, key", [
    ("experiment.secondary.mission_start=2029-01-01T00:00:00", "mission_start"),
    ("experiment.secondary.g_classes=[15.0,15.001]", "g_classes"),
])
def test_bad_settings_are_one_line_user_errors(override, key):
    with pytest.raises(UserInputError, match=key):
        S.build_settings(_config([override])[0])


def test_bad_formula_through_cli_exits_2_and_leaves_no_output(tmp_path):
    out = tmp_path / "bad"
    r = subprocess.run([str(BIN / "mcsweep"), f"hydra.run.dir={out}", *REDUCED,
                        f"experiment.secondary.f90_formula={tmp_path / 'nope.csv'}"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr[-2000:]
    lines = [ln for ln in r.stderr.strip().splitlines() if ln]
    assert len(lines) == 1 and "f90_formula" in lines[0] and "Traceback" not in r.stderr
    assert not out.exists()


# ----------------------------------------------------------------------------- reference epoch
#: Two code paths (the solution at one epoch, the closed-form propagation of the solution
#: at another) agree to rounding of a 5x5 inverse with condition up to ~1e6.
RTOL_EPOCHS = 1e-7
DAYS_PER_YEAR = 365.25  # Julian year, the unit of the proper motions


def _one_star_rows(settings, days):
    """One star at (ra, dec) = (40, -20) deg with FoV transits ``days`` after the mission start."""
    from mcsweep.scanning.ephemeris import gaia_position_au

    t = settings.start_jd + np.asarray(days, dtype=float)
    st = {"ra": np.array([40.0]), "dec": np.array([-20.0]), "parallax": np.array([2.0]),
          "pmra": np.array([8.0]), "pmdec": np.array([-5.0]), "phot_g_mean_mag": np.array([15.0]),
          "l": np.array([0.0]), "b": np.array([0.0])}
    rows = {"star": np.zeros(t.size, dtype=int), "col": np.arange(t.size), "t": t,
            "psi": np.linspace(10.0, 170.0, t.size), "obs": gaia_position_au(t)}
    return st, rows, t


def _normals(settings, setting, st, rows):
    s = dataclasses.replace(settings, reference_epoch=setting)
    return S.block_normals(st, np.array([0]), rows, rows["t"].size, s, np.random.default_rng(3))


def _times_seen_by_design(settings, setting, st, rows, monkeypatch):
    """The t - t_ep [yr] of the star's transits that go into its design matrix (Eq. 1)."""
    seen = []
    real = S.design_matrix

    def spy(*args, **kw):
        seen.append(np.asarray(args[2])[kw["mask"]])
        return real(*args, **kw)
    with monkeypatch.context() as m:
        m.setattr(S, "design_matrix", spy)
        _normals(settings, setting, st, rows)
    return seen[0]


def test_reference_epoch_setting_reaches_the_design_of_the_solutions(settings, monkeypatch):
    # A star observed only in the first year: under dataset_mean (epoch = mid-mission, 2.5 yr
    # after the start) every transit is before the epoch; under star_mean they straddle it.
    st, rows, t = _one_star_rows(settings, [20.0, 90.0, 200.0, 300.0])
    seen = {setting: _times_seen_by_design(settings, setting, st, rows, monkeypatch)
            for setting in ("dataset_mean", "star_mean", "2016-01-01T00:00:00")}
    mid = 0.5 * (settings.start_jd + settings.end_jd)
    np.testing.assert_allclose(seen["dataset_mean"], (t - mid) / DAYS_PER_YEAR, rtol=RTOL_EPOCHS)
    assert (seen["dataset_mean"] < 0).all()
    assert seen["star_mean"].min() < 0 < seen["star_mean"].max()
    assert abs(seen["star_mean"].mean()) < 1e-9
    # An ISO date (TCB) is used as given: 2016-01-01 is after every transit of 2014.
    assert (seen["2016-01-01T00:00:00"] < 0).all()
    assert settings.reference_epoch == "dataset_mean"  # the default


def _propagated(cov, dt_yr):
    """cov of (pos(t1), plx, pm) from cov of (pos(t0), plx, pm): pos(t1) = pos(t0) + dt pm."""
    T = np.eye(5)
    T[0, 3] = T[1, 4] = dt_yr
    return T @ cov @ T.T


@pytest.mark.parametrize("days, symmetric", [
    ([30.0, 400.0, 913.125, 1826.25 - 400.0, 1826.25 - 30.0], True),  # symmetric about mid-mission
    ([20.0, 90.0, 200.0, 300.0, 700.0], False),                       # early and lopsided
])
def test_position_covariance_moves_between_epochs_as_the_closed_form(settings, days, symmetric):
    st, rows, t = _one_star_rows(settings, days)
    assert settings.end_jd - settings.start_jd == pytest.approx(1826.25, rel=1e-12)
    N_ds, b_ds = _normals(settings, "dataset_mean", st, rows)
    N_sm, b_sm = _normals(settings, "star_mean", st, rows)
    dt = (0.5 * (settings.start_jd + settings.end_jd) - t.mean()) / DAYS_PER_YEAR
    sig = np.array([1.5])
    for solve in (lambda N, b: S.solve_no_prior(N, b), lambda N, b: S.solve_with_prior(N, b, sig, 10.0),
                  lambda N, b: S.solve_with_prior(N, b, 10 * sig, 10.0)):
        ds, sm = solve(N_ds, b_ds), solve(N_sm, b_sm)
        assert ds.ok.all() and sm.ok.all()
        expected = _propagated(sm.cov[0], dt)
        np.testing.assert_allclose(ds.cov[0], expected, rtol=RTOL_EPOCHS, atol=RTOL_EPOCHS * np.abs(expected).max())
        # Same noise realisation: the errors (truth: position 0 at each setting's epoch) move
        # the same way, err_pos(t1) = err_pos(t0) + dt err_pm.
        err_sm = sm.x[0] - np.array([0.0, 0.0, 2.0, 8.0, -5.0])
        np.testing.assert_allclose(ds.position[0], err_sm[:2] + dt * err_sm[3:5], rtol=RTOL_EPOCHS,
                                   atol=RTOL_EPOCHS * np.abs(sm.x[0]).max())
        if symmetric:
            assert abs(dt) < 1e-9
            np.testing.assert_allclose(ds.position_cov[0], sm.position_cov[0], rtol=RTOL_EPOCHS)
        else:
            # Far from its transits the position is less well known.
            assert np.trace(ds.position_cov[0]) > 2 * np.trace(sm.position_cov[0])


@pytest.mark.parametrize("value", ["mid-mission", "2016-02-30", "2040-01-01"])
def test_bad_reference_epoch_is_a_one_line_config_error(value):
    with pytest.raises(UserInputError, match=r"reference_epoch=.*dataset_mean.*star_mean.*ISO") as err:
        _config([f"experiment.secondary.reference_epoch={value}"])
    assert value in str(err.value) and "\n" not in str(err.value)


def test_reference_epoch_recorded_in_provenance_table2_and_report(cli_run):
    import json
    prov = json.loads((cli_run / "provenance.json").read_text())
    ep = prov["derived"]["secondary"]["reference_epoch"]
    assert ep["setting"] == "dataset_mean" and ep["iso"].startswith("2017-01-23T13:30")
    text = "reference epoch: 2017-01-23 (mid-point of the data set, TCB)"
    assert text in (cli_run / "table2.md").read_text()
    assert text.replace("reference", "Reference") in (cli_run / "report.md").read_text()
