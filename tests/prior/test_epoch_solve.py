"""mcsweep-prior solve on Gaia DR4 epoch astrometry: the command, its batches, its refusals."""

import subprocess
import sys
from importlib.resources import files
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mcsweep.errors import UserInputError
from mcsweep.prior import Prior
from mcsweep.prior.epoch_solve import solve_epoch_file

BIN = Path(sys.executable).parent
SAMPLE = Path(str(files("mcsweep") / "data" / "epoch_astrometry" / "sample_epoch_astrometry.parquet"))
REFERENCE = pd.read_csv(Path(__file__).resolve().parents[1] / "data" / "gaiasupdate" / "reference_solutions.csv")
PARAMS = ("dalpha_star_mas", "ddelta_mas", "parallax_mas", "pmra_mas_yr", "pmdec_mas_yr")
#: The issue's bar for the no-prior solution against gaiasupdate's: 0.01 of the formal error.
TOL_SIGMA = 0.01
#: A CSV copy of float32 per-transit columns (parallax factor, barycentric correction) holds
#: them as decimal text rounded to float32's ~7 digits, read back as float64: the solution
#: moves by up to ~1e-7 relative in those numbers (measured: 5e-5 of the parallax error of the
#: 304 mas star, 0 for the sources in the Parquet part), as between the archive's CSV and FITS.
TOL_TEXT_SIGMA = 1e-4
#: Real Gaia source_ids (> 2**53) for the sample's ids 0..9.
BIG = 4472832130942575873


def run(*args):
    return subprocess.run([str(BIN / "mcsweep-prior"), *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def sources(ids, path):
    """A gaia_source extract for ``ids``: fixed directions over the sky, G from 8 to 19."""
    n = len(ids)
    pd.DataFrame({"source_id": ids, "ra": np.linspace(5, 355, n), "dec": np.linspace(-70, 70, n),
                  "phot_g_mean_mag": np.linspace(8, 19, n)}).to_csv(path, index=False)
    return path


@pytest.fixture
def sample_sources(tmp_path):
    return sources(range(10), tmp_path / "sources.csv")


def test_command_no_prior_columns_are_the_source_update(tmp_path, sample_sources):
    out = tmp_path / "sol.parquet"
    r = run("solve", SAMPLE, "--sources", sample_sources, "--out", out)
    assert r.returncode == 0, r.stderr
    got = pd.read_parquet(out).set_index("source_id")
    ref = REFERENCE[(REFERENCE["file"] == SAMPLE.name) & (REFERENCE["model"] == "5p")
                    & (REFERENCE["variant"] == "file_excess_noise")].set_index("source_id").loc[got.index]
    for p in PARAMS:
        assert np.all(np.abs(got["no_prior_" + p] - ref[p]) <= TOL_SIGMA * ref[p + "_error"]), p
    assert (got["model"] == "5p").all()
    assert np.allclose(got["reference_epoch_tcb_jd"], 2457936.875)
    assert list(got["n_ccd_al"]) == list(ref["n_obs"])
    # Every sample source has 26-53 visibility periods over 4.6-5.4 yr: the data suffice.
    assert (got["solution"] == "five_parameter").all()


def test_exact_source_ids_and_six_parameters(tmp_path):
    df = pd.read_parquet(SAMPLE)
    df["sourceId"] = df["sourceId"] + BIG
    epoch = tmp_path / "epochs.parquet"
    df.to_parquet(epoch, index=False)
    src = sources([BIG + i for i in range(10)], tmp_path / "src.csv")
    out = tmp_path / "sol.csv"
    r = run("solve", epoch, "--sources", src, "--out", out, "--model", "6p")
    assert r.returncode == 0, r.stderr
    got = pd.read_csv(out, dtype={"source_id": str})
    assert list(got["source_id"]) == [str(BIG + i) for i in range(10)]
    ref = REFERENCE[(REFERENCE["file"] == SAMPLE.name) & (REFERENCE["model"] == "6p")
                    & (REFERENCE["variant"] == "file_excess_noise")].sort_values("source_id")
    assert np.all(np.abs(got["no_prior_parallax_mas"].to_numpy() - ref["parallax_mas"].to_numpy())
                  <= TOL_SIGMA * ref["parallax_mas_error"].to_numpy())
    assert np.all(np.isfinite(got["pseudocolour"]))


def test_batches_and_workers_change_nothing(sample_sources):
    prior = Prior.paper()
    whole = pd.concat(solve_epoch_file(SAMPLE, sample_sources, prior), ignore_index=True)
    small = pd.concat(solve_epoch_file(SAMPLE, sample_sources, prior, batch_rows=37), ignore_index=True)
    pd.testing.assert_frame_equal(whole, small.sort_values("source_id", ignore_index=True), check_exact=True)

    def run_here(fn, items):  # an executor in completion order: here, reversed
        return [fn(i) for i in reversed(list(items))]

    par = pd.concat(solve_epoch_file(SAMPLE, sample_sources, prior, batch_rows=37, run=run_here, n_workers=2),
                    ignore_index=True)
    pd.testing.assert_frame_equal(small, par, check_exact=True)


def test_jobs_2_is_bit_identical(tmp_path, sample_sources):
    outs = []
    for jobs in (1, 2):
        out = tmp_path / f"sol{jobs}.parquet"
        r = run("solve", SAMPLE, "--sources", sample_sources, "--out", out, "--jobs", jobs)
        assert r.returncode == 0, r.stderr
        outs.append(pd.read_parquet(out))
    pd.testing.assert_frame_equal(*outs, check_exact=True)


def test_reference_epoch_spellings(tmp_path, sample_sources):
    got = {}
    for setting in ("J2017.5", "2017.5", "2017-07-02T09:00:00", "star_mean"):
        out = tmp_path / "sol.csv"
        r = run("solve", SAMPLE, "--sources", sample_sources, "--out", out, "--reference-epoch", setting)
        assert r.returncode == 0, r.stderr
        got[setting] = pd.read_csv(out)
    pd.testing.assert_frame_equal(got["J2017.5"], got["2017.5"])
    # J2017.5 is 2017-07-02T09:00:00 TCB (JD 2457936.875).
    assert np.allclose(got["2017-07-02T09:00:00"]["reference_epoch_tcb_jd"], 2457936.875, rtol=0, atol=1e-9)
    # The epoch moves the position, not the parallax.
    assert np.allclose(got["star_mean"]["no_prior_parallax_mas"], got["J2017.5"]["no_prior_parallax_mas"],
                       rtol=1e-9, atol=0)
    assert not np.allclose(got["star_mean"]["reference_epoch_tcb_jd"], 2457936.875)


def test_rows_of_a_source_not_together_are_refused(tmp_path, sample_sources):
    df = pd.read_parquet(SAMPLE)
    moved = pd.concat([df.iloc[5:], df.iloc[:5]], ignore_index=True)  # source 0 split: head and tail
    path = tmp_path / "split.parquet"
    moved.to_parquet(path, index=False)
    with pytest.raises(UserInputError, match="source_id 0 are not together"):
        list(solve_epoch_file(path, sample_sources, Prior.paper(), batch_rows=100))
    # Within one batch any order is fine.
    assert len(pd.concat(solve_epoch_file(path, sample_sources, Prior.paper()))) == 10


def bad_cases(tmp_path, sample_sources):
    df = pd.read_parquet(SAMPLE)
    no_ccd = df.copy()
    no_ccd["usedByAgisAl"] = [np.zeros(len(v), bool) if s == 3 else v for s, v in
                              zip(no_ccd["sourceId"], no_ccd["usedByAgisAl"])]
    no_ccd_path = tmp_path / "no_ccd.parquet"
    no_ccd.to_parquet(no_ccd_path, index=False)
    not_epochs = tmp_path / "not_epochs.parquet"
    df[["sourceId", "centroidPosAl"]].to_parquet(not_epochs, index=False)
    few = sources(range(9), tmp_path / "few.csv")
    return [
        ((not_epochs, "--sources", sample_sources), "lacks"),
        ((SAMPLE, "--sources", few), "source_id 9 has no row in few.csv"),
        ((no_ccd_path, "--sources", sample_sources), "source_id 3 has no usable AL CCD"),
        ((SAMPLE, "--sources", sample_sources, "--model", "7p"), "--model '7p' is not accepted"),
        ((SAMPLE,), "expected --sources"),
    ]


def test_bad_input_one_line_exit_2_nothing_written(tmp_path, sample_sources):
    for args, message in bad_cases(tmp_path, sample_sources):
        out = tmp_path / "sol.csv"
        r = run("solve", *args, "--out", out)
        assert r.returncode == 2, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert message in r.stderr, (message, r.stderr)
        assert not out.exists()
        assert not list(tmp_path.glob("*.tmp*")) and not list(tmp_path.glob(".sol*"))


def test_a_directory_of_files_is_one_input(tmp_path, sample_sources):
    df = pd.read_parquet(SAMPLE)
    folder = tmp_path / "epochs"
    folder.mkdir()
    df[df["sourceId"] < 4].to_parquet(folder / "part-0.parquet", index=False)
    # The archive's CSV form: arrays as '(a, b, ...)' text, every digit kept.
    text = df[df["sourceId"] >= 4].copy()
    for c in text.columns:
        if text[c].dtype == object:
            text[c] = ["(" + ", ".join(repr(getattr(v, "item", lambda: v)()) for v in cell) + ")" for cell in text[c]]
    text.to_csv(folder / "part-1.csv", index=False)
    (folder / "README.md").write_text("not a table: skipped")
    (folder / "MD5SUM").write_text("")
    (folder / "notes.txt").write_text("a,b\n1,2\n")  # a table by its suffix, not epoch astrometry
    whole = pd.concat(solve_epoch_file(SAMPLE, sample_sources, Prior.paper()), ignore_index=True)
    with pytest.raises(UserInputError, match="notes.txt: not Gaia epoch astrometry"):
        list(solve_epoch_file(folder, sample_sources, Prior.paper()))
    (folder / "notes.txt").unlink()
    parts = pd.concat(solve_epoch_file(folder, sample_sources, Prior.paper()), ignore_index=True)
    assert list(parts["source_id"]) == list(whole["source_id"])
    sigma = whole["no_prior_parallax_error_mas"]
    assert np.all(np.abs(parts["no_prior_parallax_mas"] - whole["no_prior_parallax_mas"]) <= TOL_TEXT_SIGMA * sigma)
    df.to_parquet(folder / "part-2.parquet", index=False)  # every source again
    with pytest.raises(UserInputError, match="not together"):
        list(solve_epoch_file(folder, sample_sources, Prior.paper()))


def test_dr4_format_with_ra0_dec0_g_mag_needs_no_sources_table(tmp_path):
    """DR4's own format carries each transit's reference position and G (the pre-release's
    ra0, dec0, g_mag): the file alone gives the solution with the prior."""
    df = pd.read_parquet(SAMPLE)
    src = pd.read_csv(Path(str(files("mcsweep") / "data" / "epoch_astrometry" / "sample_sources.csv")), comment="#")
    by_id = src.set_index("source_id")
    df["ra0"] = by_id.loc[df["sourceId"], "ra"].to_numpy()
    df["dec0"] = by_id.loc[df["sourceId"], "dec"].to_numpy()
    rng = np.random.default_rng(1)
    g = by_id.loc[df["sourceId"], "phot_g_mean_mag"].to_numpy() + rng.normal(0, 0.01, len(df))
    g[::7] = np.nan  # transits without a G: the median of the others
    df["g_mag"] = g
    path = tmp_path / "dr4.parquet"
    df.to_parquet(path, index=False)
    src_path = tmp_path / "src.csv"
    src[["source_id", "ra", "dec", "phot_g_mean_mag"]].to_csv(src_path, index=False)
    alone = pd.concat(solve_epoch_file(path, None, Prior.paper()), ignore_index=True)
    given = pd.concat(solve_epoch_file(path, src_path, Prior.paper()), ignore_index=True)
    assert np.allclose(alone["ra"], given["ra"], rtol=0, atol=1e-12)
    assert np.all(np.abs(alone["phot_g_mean_mag"] - given["phot_g_mean_mag"]) < 0.02)
    # The prior changes with G by much less than its own size over 0.02 mag.
    assert np.allclose(alone["sigma_prior_parallax_mas"], given["sigma_prior_parallax_mas"], rtol=0.01)
    pd.testing.assert_series_equal(alone["no_prior_parallax_mas"], given["no_prior_parallax_mas"])


def test_dask_cluster_gives_the_same_table(tmp_path, sample_sources):
    pytest.importorskip("dask.distributed", reason="--dask needs the dask extra")
    outs = []
    for extra in ((), ("--dask", "--jobs", "2")):
        out = tmp_path / f"sol{len(extra)}.parquet"
        r = run("solve", SAMPLE, "--sources", sample_sources, "--out", out, *extra)
        assert r.returncode == 0, r.stderr
        outs.append(pd.read_parquet(out))
    pd.testing.assert_frame_equal(*outs, check_exact=True)


@pytest.mark.parametrize("suffix", [".fits", ".vot", ".ecsv"])
def test_astropy_outputs_keep_exact_ids(tmp_path, suffix):
    from astropy.table import Table

    df = pd.read_parquet(SAMPLE)
    df["sourceId"] = df["sourceId"] + BIG
    epoch = tmp_path / "epochs.parquet"
    df.to_parquet(epoch, index=False)
    src = sources([BIG + i for i in range(10)], tmp_path / "src.csv")
    out = tmp_path / f"sol{suffix}"
    r = run("solve", epoch, "--sources", src, "--out", out)
    assert r.returncode == 0, r.stderr
    assert list(Table.read(out)["source_id"]) == [BIG + i for i in range(10)]


def test_shuffled_parquet_in_one_batch_and_null_arrays(tmp_path, sample_sources):
    df = pd.read_parquet(SAMPLE)
    whole = pd.concat(solve_epoch_file(SAMPLE, sample_sources, Prior.paper()), ignore_index=True)
    shuffled = df.sample(frac=1.0, random_state=3)
    path = tmp_path / "shuffled.parquet"
    shuffled.to_parquet(path, index=False)
    got = pd.concat(solve_epoch_file(path, sample_sources, Prior.paper()), ignore_index=True)
    sigma = whole["no_prior_parallax_error_mas"]
    assert np.all(np.abs(got["no_prior_parallax_mas"] - whole["no_prior_parallax_mas"]) <= 1e-9 * sigma)
    # A transit whose centroids are null (an empty array) is not used; the file is still solved.
    nulled = df.copy()
    nulled["centroidPosAl"] = [np.array([], float) if i == 5 else v for i, v in enumerate(nulled["centroidPosAl"])]
    path = tmp_path / "null.parquet"
    nulled.to_parquet(path, index=False)
    got = pd.concat(solve_epoch_file(path, sample_sources, Prior.paper()), ignore_index=True)
    row = got["source_id"] == df["sourceId"].iloc[5]
    n_used = int(np.sum(np.asarray(df["usedByAgisAl"].iloc[5], bool)))
    assert int(got.loc[row, "n_ccd_al"].iloc[0]) == int(whole.loc[row, "n_ccd_al"].iloc[0]) - n_used


def test_times_in_another_unit_are_refused(tmp_path, sample_sources):
    df = pd.read_parquet(SAMPLE)
    df["obsTimeTcb"] = [np.asarray(v, float) / 86400e9 for v in df["obsTimeTcb"]]  # days, not ns
    path = tmp_path / "days.parquet"
    df.to_parquet(path, index=False)
    with pytest.raises(UserInputError, match="outside Gaia's mission"):
        list(solve_epoch_file(path, sample_sources, Prior.paper()))
