"""experiment=real_epochs: random subsets of real Gaia DR4 epoch astrometry against each
source's all-transit solution.

The science is checked against references independent of the experiment's code: synthetic
epoch files whose centroids are written here from the AL design equation (Lindegren et al.
2012, A&A 538, A78, Sect. 5.2) with a known truth, on the vendored sample's real geometry
(times, scan angles, parallax factors, CCD errors); closed forms (noise-free data give zero
error) and the Gaussian expectation (the fraction inside the P ellipse is P).
"""

from __future__ import annotations

import json
import subprocess
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from mcsweep.command.schema import ExecutionConf
from mcsweep.command.validate import compose_config, to_config
from mcsweep.errors import UserInputError
from mcsweep.experiments.real_epochs import runner
from mcsweep.experiments.real_epochs.inputs import read_inputs
from mcsweep.experiments.real_epochs.solutions import ChunkSettings, solve_chunk, solve_subsets, solve_truth
from mcsweep.experiments.real_epochs.subsets import choose_items, source_layout, subset_rows
from mcsweep.experiments.real_epochs.table import (HOLD_LIMIT_SIGMA, pooled_percentiles,
                                                   transit_unit_weight_variance)
from mcsweep.runtime.store import ResultStore

BIN = Path(sys.executable).parent
SAMPLE = resources.files("mcsweep").joinpath("data", "epoch_astrometry")
#: The DR4 files' time origin, 2010-01-01T00:00 TCB, as a Julian date (their TIMESYS origin).
TCB_ORIGIN_JD = 2455197.5
#: J2017.5 TCB, Gaia DR4's reference epoch: 2451545.0 + 17.5 x 365.25.
J2017_5_JD = 2457936.875
#: Noise-free data: the position error is rounding only (positions ~ 1e3 mas, float64).
ZERO_ERROR_MAS = 1e-6
#: ... and where the subset's position is ill-determined (two nearly parallel scans: major axis
#: up to ~1e5 mas), rounding relative to the ellipse's major axis (condition ~1e10 x 2.2e-16).
ROUNDING_PER_AXIS = 1e-6
#: numpy's percentile interpolates as b - (b - a)(1 - t) where t >= 0.5, ours as a + (b - a) t.
LERP_RTOL = 1e-12
P = 0.9


def synthetic_epoch_files(tmp: Path, x_true, *, copies: int, repeat: int = 1, seed: int = 0, noise: bool = True):
    """An epoch file (DPAC columns, Parquet) and its sources table: each of the sample's 10
    sources' real geometry ``repeat`` times (rows repeated, fresh noise), ``copies`` sources
    each, with centroids from the truth ``x_true`` (alpha*, delta [mas], parallax [mas],
    pmra, pmdec [mas/yr] at J2017.5) plus N(0, centroidPosErrorAl) per CCD; excess noise 0."""
    with resources.as_file(SAMPLE.joinpath("sample_epoch_astrometry.parquet")) as p:
        df = pq.read_table(p).to_pandas()
    with resources.as_file(SAMPLE.joinpath("sample_sources.csv")) as p:
        src = pd.read_csv(p, comment="#")
    rng = np.random.default_rng(seed)
    x = np.asarray(x_true, float)
    parts, rows_src = [], []
    for c in range(copies):
        for g in range(10):
            rows = pd.concat([df[df["sourceId"] == g]] * repeat, ignore_index=True)
            cen = []
            for r in rows.itertuples():
                t_yr = ((np.asarray(r.obsTimeTcb) + r.obsTimeBaryCorr) / 86400e9 + TCB_ORIGIN_JD - J2017_5_JD) / 365.25
                th = np.deg2rad(np.asarray(r.scanPosAngle))
                w = (np.sin(th) * (x[0] + t_yr * x[3]) + np.cos(th) * (x[1] + t_yr * x[4])
                     + r.parallaxFactorAl * x[2])
                if noise:
                    w = w + np.asarray(r.centroidPosErrorAl, float) * rng.standard_normal(w.size)
                cen.append(w)
            sid = 1000 * (c + 1) + g
            parts.append(rows.assign(centroidPosAl=cen, sourceId=sid, agisSourceExcessNoise=0.0))
            s = src[src["source_id"] == g].iloc[0]
            rows_src.append({"source_id": sid, "ra": s["ra"], "dec": s["dec"], "phot_g_mean_mag": s["phot_g_mean_mag"]})
    epoch, sources = tmp / "epochs.parquet", tmp / "sources.csv"
    pq.write_table(pa.Table.from_pandas(pd.concat(parts, ignore_index=True), preserve_index=False), epoch)
    pd.DataFrame(rows_src).to_csv(sources, index=False)
    return epoch, sources


def _settings(**kw) -> ChunkSettings:
    base = dict(seed=7, draws=50, sizes={"transits": (2, 6), "visits": (3, 6)}, priors=("F90", "1000mas"),
                confidence=P, ratio_R=10.0)
    return ChunkSettings(**{**base, **kw})


# --------------------------------------------------------------------------- closed forms
def test_a_subset_of_all_transits_reproduces_the_truth():
    inp = read_inputs(None, None)
    truth = solve_truth(inp.obs)
    # k = every transit of the source: one subset per source, the whole data set, solved at
    # its mean epoch with a negligible prior; the truth propagated there is the same solution.
    lay = source_layout(inp.obs)
    n = lay.n_items["transits"]
    sel = np.zeros((n.size, 1, n.max() + 1), bool)
    sel[:, 0, :-1] = np.arange(n.max())[None, :] < n[:, None]
    rows, number = subset_rows(lay.row_start, lay.n_rows, lay.item_of_row["transits"], sel)
    assert np.array_equal(np.sort(rows), np.arange(len(inp.obs)))
    res = solve_subsets(inp.obs, truth.x, {"loose": np.full(n.size, 1e12)}, rows, number, 1, ratio_R=10.0,
                        confidence=P)
    assert np.abs(res.dpos["loose"]).max() < ZERO_ERROR_MAS
    assert (res.flags["loose"] == 1).all()


def test_noise_free_subsets_have_zero_error_in_closed_form(tmp_path):
    # Star A: position offset, no parallax or proper motion. b0 = N0 x and N_p x = 0 (the prior
    # has no position part, Eq. 18), so every prior and position only give x exactly.
    epoch, sources = synthetic_epoch_files(tmp_path, [3.0, -2.0, 0.0, 0.0, 0.0], copies=1, noise=False)
    inp = read_inputs(str(epoch), str(sources))
    truth = solve_truth(inp.obs)
    assert np.abs(truth.x - [3.0, -2.0, 0.0, 0.0, 0.0]).max() < ZERO_ERROR_MAS
    s = truth.source_id.size
    lay = source_layout(inp.obs)
    for unit, k in (("transits", 2), ("transits", 6), ("visits", 3)):
        sel = choose_items(7, lay.source_id, lay.n_items[unit], unit, k, 50)
        rows, number = subset_rows(lay.row_start, lay.n_rows, lay.item_of_row[unit], sel)
        res = solve_subsets(inp.obs, truth.x, {"F90": np.full(s, 0.5), "1000mas": np.full(s, 1000.0)}, rows, number,
                            50, ratio_R=10.0, confidence=P)
        for prior in ("F90", "1000mas", "none"):
            ok = res.flags[prior] >= 0
            assert ok.mean() > 0.95
            err = np.hypot(res.dpos[prior][ok, 0], res.dpos[prior][ok, 1])
            # rounding grows with the ellipse's elongation (nearly parallel scans): bound it by the major axis
            major = np.sqrt(np.linalg.eigvalsh(res.cov[prior][ok])[:, 1])
            assert (err <= ZERO_ERROR_MAS + ROUNDING_PER_AXIS * major).all(), (unit, k, prior)
    # Star B: a fast nearby star. Without prior (1e12 mas) a subset of 6 visits determines all
    # five parameters, and its position at its own mean epoch t is the truth's linear motion
    # alpha*(t) = alpha*(J2017.5) + mu t, which the subsets' epochs test.
    x_b = [40.0, 25.0, 120.0, -900.0, 450.0]
    epoch, sources = synthetic_epoch_files(tmp_path, x_b, copies=1, noise=False)
    inp = read_inputs(str(epoch), str(sources))
    truth = solve_truth(inp.obs)
    assert np.abs(truth.x - x_b).max() < ZERO_ERROR_MAS
    df = solve_chunk(_settings(sizes={"visits": (6,)}, priors=("loose",)), inp.obs, truth.x,
                     {"loose": np.full(truth.source_id.size, 1e12)})
    assert (df["inside_loose"] >= 0).all() and df["err_loose_mas"].max() < ZERO_ERROR_MAS
    assert df["epoch_offset_yr"].std() > 0.1  # the subsets' epochs differ: the motion is tested


# --------------------------------------------------------------------------- Monte Carlo
def test_fraction_inside_with_a_loose_prior_is_p_for_gaussian_errors(tmp_path):
    # Truth zero parallax and proper motion, Gaussian CCD errors of the stated sizes: with
    # 1000 mas (Table 2's loose prior) and 6 transits the data fix all five parameters, the
    # prior is centred on the truth, and the P ellipse holds P of the errors. The truth is the
    # all-transit solution, which shares the subset's transits: Var(subset - truth) =
    # C_sub - C_all (Hausman 1978, Econometrica 46, 1251; both least squares, nested data), so
    # the fraction is P raised by at most 1 - (1 - P)^(1 / (1 - k / n)) - P for k of n
    # transits; each geometry is repeated 8 times to keep that small.
    k, repeat, draws = 6, 8, 200
    epoch, sources = synthetic_epoch_files(tmp_path, [3.0, -2.0, 0.0, 0.0, 0.0], copies=2, repeat=repeat, seed=3)
    inp = read_inputs(str(epoch), str(sources))
    truth = solve_truth(inp.obs)
    s = truth.source_id.size
    df = solve_chunk(_settings(draws=draws, sizes={"transits": (k,)}, priors=("1000mas",)), inp.obs, truth.x,
                     {"1000mas": np.full(s, 1000.0)})
    flags = df["inside_1000mas"].to_numpy()
    n = int((flags >= 0).sum())
    assert n == s * draws
    frac = (flags == 1).sum() / n
    n_min = int(truth.n_transits.min())
    shift = 1 - (1 - P) ** (1 / (1 - k / n_min)) - P
    sigma = np.sqrt(P * (1 - P) / n)
    assert P - 4 * sigma <= frac <= P + shift + 4 * sigma, (frac, shift, sigma)
    # Independent CCD errors: each transit's mean residual has its formal variance, so the
    # transit-level unit-weight variance is (n - 5) / n on average (the fit takes 5 dof).
    uwv = transit_unit_weight_variance(inp.obs, truth)
    expected = np.mean((truth.n_transits - 5) / truth.n_transits)
    assert abs(uwv.mean() - expected) < 4 * np.sqrt(np.mean(2 / truth.n_transits) / s)


def test_pooled_bootstrap_percentile_is_numpys_on_the_pooled_sample(rng):
    values = rng.exponential(3.0, 300)
    owner = rng.integers(0, 7, 300)
    weights = rng.integers(0, 3, (20, 7))
    weights[0] = 0
    got = pooled_percentiles(values, owner, weights, 90.0)
    assert np.isnan(got[0])
    for b in range(1, 20):
        pooled = np.concatenate([np.repeat(values[owner == s], weights[b, s]) for s in range(7)])
        want = np.percentile(pooled, 90.0) if pooled.size else np.nan
        np.testing.assert_allclose(got[b], want, rtol=LERP_RTOL)


def test_star_classes_follow_the_named_limit():
    inp = read_inputs(None, None)
    config = to_config(compose_config(["experiment=real_epochs"]))
    prep = runner.prepare(config)
    x = prep.truth.x
    held = ((np.abs(x[:, 2]) <= HOLD_LIMIT_SIGMA * prep.sigma_f90_mas)
            & (np.hypot(x[:, 3], x[:, 4]) <= HOLD_LIMIT_SIGMA * 10.0 * prep.sigma_f90_mas))
    assert list(prep.star_class) == ["held" if h else "not_held" for h in held]
    # The vendored sample: 7 of its 10 sources are nearby or fast stars the prior cannot hold.
    assert (prep.star_class == "not_held").sum() == 7 and inp.sources.source_id.size == 10


# --------------------------------------------------------------------------- execution
def test_results_are_bit_identical_for_one_and_two_workers(tmp_path):
    epoch, sources = synthetic_epoch_files(tmp_path, [0.0, 0.0, 2.0, 5.0, -3.0], copies=4, seed=5)
    config = to_config(compose_config(["experiment=real_epochs", f"experiment.real_epochs.epoch_file={epoch}",
                                       f"experiment.real_epochs.sources_file={sources}",
                                       "experiment.real_epochs.draws=20", "experiment.real_epochs.transits=[2]",
                                       "experiment.real_epochs.visits=[3]", "experiment.real_epochs.bootstrap=100"]))
    prep = runner.prepare(config)
    plan = runner.chunk_plan(prep)
    assert len(plan) == 2  # 40 sources: the executor has two chunks to share
    tables = []
    for n_jobs in (1, 2):
        store = ResultStore(tmp_path / f"chunks{n_jobs}", "hash")
        runner.compute(prep, store, ExecutionConf(n_jobs=n_jobs, progress=False))
        texts = runner.aggregate(prep, store, config.experiment.real_epochs)
        tables.append(([store.read(cid) for cid, _ in plan], texts))
    (one, text_one), (two, text_two) = tables
    for a, b in zip(one, two):
        pd.testing.assert_frame_equal(a, b, check_exact=True)
    assert text_one == text_two


def test_inputs_changed_under_a_run_are_refused(tmp_path):
    (tmp_path / "provenance.json").write_text(json.dumps(
        {"derived": {"real_epochs": {"input_sha256": {"epoch_file": "a" * 64, "sources_file": "b" * 64}}}}))
    with pytest.raises(UserInputError, match="other input files .*epoch_file changed"):
        runner.check_same_inputs(tmp_path, {"epoch_file": "c" * 64, "sources_file": "b" * 64})


def test_config_mistakes_are_one_line():
    with pytest.raises(UserInputError, match=r"experiment.real_epochs.sources_file=None is not accepted"):
        to_config(compose_config(["experiment=real_epochs", "experiment.real_epochs.epoch_file=x.parquet"]))
    with pytest.raises(UserInputError, match=r"experiment.real_epochs.transits=\[1, 2\] is not accepted"):
        to_config(compose_config(["experiment=real_epochs", "experiment.real_epochs.transits=[1,2]"]))
    with pytest.raises(UserInputError, match=r"experiment.real_epochs.priors entry 'F9O'"):
        to_config(compose_config(["experiment=real_epochs", "experiment.real_epochs.priors=[F9O]"]))


# --------------------------------------------------------------------------- the command
def _mcsweep(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "mcsweep"), "experiment=real_epochs", "execution.progress=false", *args],
                          capture_output=True, text=True, timeout=300)


def test_a_bad_path_is_one_line_exit_2_nothing_written(tmp_path):
    out = tmp_path / "run"
    r = _mcsweep(f"hydra.run.dir={out}", f"experiment.real_epochs.epoch_file={tmp_path / 'nothing.parquet'}",
                 f"experiment.real_epochs.sources_file={tmp_path / 'nothing.csv'}")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "nothing.parquet does not exist" in lines[0], r.stderr
    assert not out.exists() or not any(out.iterdir())


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("real_epochs") / "run"
    r = _mcsweep(f"hydra.run.dir={out}")
    assert r.returncode == 0, r.stderr
    return out


def test_the_default_sample_runs_end_to_end(default_run):
    table = pd.read_csv(default_run / "real_epochs.csv")
    assert len(table) == 8 * 4 * 3  # (4 transits + 4 visits sizes) x 4 priors x 3 classes
    assert set(table["prior"]) == {"F90", "10F90", "1000mas", "none"}
    assert {"p_error_mas", "p_error_boot_lo_mas", "p_error_boot_hi_mas", "fraction_boot_lo"} <= set(table.columns)
    n = table.groupby("star_class")["n_sources"].max()
    assert (n["held"], n["not_held"], n["all"]) == (3, 7, 10)
    ok = table["n_valid"] > 0
    assert ((table.loc[ok, "fraction_lo"] <= table.loc[ok, "fraction_inside"])
            & (table.loc[ok, "fraction_inside"] <= table.loc[ok, "fraction_hi"])).all()
    assert (table.loc[ok, "n_draws"] == 200 * table.loc[ok, "n_sources"]).all()
    per_source = pd.read_csv(default_run / "real_epochs_sources.csv")
    assert len(per_source) == 10 * 8 * 4 and per_source["n_draws"].eq(200).all()
    # The class counts in the table are the per-source rows' sums.
    f90 = per_source[(per_source["prior"] == "F90") & (per_source["unit"] == "visits") & (per_source["k"] == 6)]
    row = table[(table["prior"] == "F90") & (table["unit"] == "visits") & (table["k"] == 6)
                & (table["star_class"] == "all")].iloc[0]
    assert f90["n_inside"].sum() == row["n_inside"] and f90["n_valid"].sum() == row["n_valid"]
    report = (default_run / "report.md").read_text()
    assert "Real Gaia DR4 epoch astrometry" in report and "7 of the 10 are nearby or fast stars" in report
    assert "recovered from the parallax factors" in report and (default_run / "real_epochs_fraction.png").is_file()
    prov = json.loads((default_run / "provenance.json").read_text())
    assert prov["kind"] == "real_epochs" and "subsets" in prov["seeds"]["real_epochs"]
    assert prov["derived"]["real_epochs"]["transit_range"] == [49, 177]


def test_a_rerun_resumes_keeping_its_chunks(default_run):
    chunks = sorted((default_run / "real_epochs_chunks").glob("*.parquet"))
    before = {p.name: p.stat().st_mtime_ns for p in chunks}
    table = (default_run / "real_epochs.csv").read_bytes()
    # accept_other_versions: others may edit the working tree between the two runs (the code
    # version of a dirty checkout hashes its diff); the version check is the store's own.
    r = _mcsweep(f"hydra.run.dir={default_run}", "resume.accept_other_versions=true")
    assert r.returncode == 0, r.stderr
    assert {p.name: p.stat().st_mtime_ns for p in (default_run / "real_epochs_chunks").glob("*.parquet")} == before
    assert (default_run / "real_epochs.csv").read_bytes() == table
