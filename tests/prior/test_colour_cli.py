"""mcsweep-prior annotate and solve with a colour / mean-centred prior (a synthetic run)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from astropy import units as u
from astropy.table import Table

from mcsweep.astrometry.solve import normal_equations, solve_with_prior
from mcsweep.galactic import galactic_from_icrs
from mcsweep.prior import Prior

BIN = Path(sys.executable).parent
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "prior_solve"
#: ICRS -> galactic by the fast rotation in the command vs the same in the test: identical
#: code, different array lengths (batches), so only last-bit differences of numpy kernels.
RTOL_PATHS = 1e-12
#: A 5 x 5 solve by Cholesky (the library) vs numpy.linalg.solve (LU) of the same system,
#: condition <= 1e8: ~8 digits at worst.
RTOL_SOLVE = 1e-7
ATOL_MAS = 1e-9


def run(*args):
    return subprocess.run([str(BIN / "mcsweep-prior"), *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def _catalogue(n=300, seed=4):
    rng = np.random.default_rng(seed)
    bp_rp = rng.uniform(-0.5, 3.0, n)
    bp_rp[::4] = np.nan
    return pd.DataFrame({"source_id": np.arange(n, dtype=np.int64), "ra": rng.uniform(0, 360, n),
                         "dec": np.degrees(np.arcsin(rng.uniform(-1, 1, n))), "phot_g_mean_mag": rng.uniform(5, 13, n),
                         "bp_rp": bp_rp})


def _expected(prior, cat, colour):
    l_deg, b_deg = galactic_from_icrs(cat["ra"].to_numpy(), cat["dec"].to_numpy())
    g = cat["phot_g_mean_mag"].to_numpy()
    pmra, pmdec = prior.mean_pm_masyr(l_deg, b_deg, g, colour)
    return {"sigma_f90_parallax": prior.sigma_parallax_mas(l_deg, b_deg, g, colour),
            "prior_mean_parallax_mas": prior.mean_parallax_mas(l_deg, b_deg, g, colour),
            "prior_mean_pmra_mas_yr": pmra, "prior_mean_pmdec_mas_yr": pmdec,
            "prior_colour_bin": prior.colour_bin_label(colour)}


def _check(got, exp):
    for name, values in exp.items():
        if name == "prior_colour_bin":
            assert list(got[name]) == list(values), name
        else:
            np.testing.assert_allclose(np.asarray(got[name], float), values, rtol=RTOL_PATHS, atol=1e-13,
                                       err_msg=name)


def test_annotate_with_bp_rp_column(colour_mean_run, tmp_path):
    cat = _catalogue()
    cat.to_csv(tmp_path / "in.csv", index=False)
    r = run("annotate", tmp_path / "in.csv", "--out", tmp_path / "out.csv", "--run", colour_mean_run)
    assert r.returncode == 0, r.stderr
    got = pd.read_csv(tmp_path / "out.csv", keep_default_na=False, na_values=[""])
    assert list(got.columns) == list(cat.columns) + ["sigma_f90_parallax", "sigma_f90_pm", "prior_colour_bin",
                                                     "prior_mean_parallax_mas", "prior_mean_pmra_mas_yr",
                                                     "prior_mean_pmdec_mas_yr"]
    prior = Prior.from_run(colour_mean_run)
    _check(got, _expected(prior, cat, cat["bp_rp"].to_numpy()))
    assert (got["prior_colour_bin"][::4] == "colour_blind").all()
    assert set(got["prior_colour_bin"]) == {"colour_blind", "-1..0.56", "0.56..1.23", "1.23..6"}


def test_annotate_names_the_prior_centre_as_solve_does_and_keeps_the_old_names_on_request(colour_mean_run, tmp_path):
    cat = _catalogue(seed=7)
    cat.to_csv(tmp_path / "in.csv", index=False)
    r = run("annotate", tmp_path / "in.csv", "--out", tmp_path / "old.csv", "--run", colour_mean_run,
            "--old-mean-columns")
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("deprecated") == 1 and "prior_mean_parallax_mas" in r.stderr
    got = pd.read_csv(tmp_path / "old.csv", keep_default_na=False, na_values=[""])
    assert list(got.columns)[-3:] == ["prior_mean_parallax", "prior_mean_pmra", "prior_mean_pmdec"]
    exp = _expected(Prior.from_run(colour_mean_run), cat, cat["bp_rp"].to_numpy())
    _check(got.rename(columns=dict(zip(got.columns[-3:], ("prior_mean_parallax_mas", "prior_mean_pmra_mas_yr",
                                                            "prior_mean_pmdec_mas_yr")))), exp)


def test_annotate_with_bp_and_rp_magnitudes(colour_mean_run, tmp_path):
    cat = _catalogue(seed=5)
    rp = cat["phot_g_mean_mag"] - 0.3
    bp = (rp + cat["bp_rp"]).to_numpy()
    table = pa.table({"source_id": cat["source_id"], "ra": cat["ra"], "dec": cat["dec"],
                      "phot_g_mean_mag": cat["phot_g_mean_mag"],
                      "phot_bp_mean_mag": pa.array(bp, mask=np.isnan(bp)),  # Gaia's nulls
                      "phot_rp_mean_mag": rp})
    pq.write_table(table, tmp_path / "in.parquet")
    r = run("annotate", tmp_path / "in.parquet", "--out", tmp_path / "out.parquet", "--run", colour_mean_run)
    assert r.returncode == 0, r.stderr
    got = pq.read_table(tmp_path / "out.parquet")
    assert got.schema.field("prior_mean_pmra_mas_yr").metadata[b"unit"] == b"mas / yr"
    prior = Prior.from_run(colour_mean_run)
    _check(got.to_pandas(), _expected(prior, cat, bp - rp.to_numpy()))


def test_annotate_without_colour_columns_gets_the_colour_blind_prior(colour_run, tmp_path):
    cat = _catalogue(seed=6).drop(columns=["bp_rp"])
    t = Table.from_pandas(cat)
    t["ra"].unit = t["dec"].unit = u.deg
    t.write(tmp_path / "in.fits")
    r = run("annotate", tmp_path / "in.fits", "--out", tmp_path / "out.ecsv", "--run", colour_run)
    assert r.returncode == 0, r.stderr
    got = Table.read(tmp_path / "out.ecsv")
    assert got.colnames == cat.columns.tolist() + ["sigma_f90_parallax", "sigma_f90_pm", "prior_colour_bin"]
    assert (got["prior_colour_bin"] == "colour_blind").all()
    exp = _expected(Prior.from_run(colour_run), cat, None)
    np.testing.assert_allclose(got["sigma_f90_parallax"], exp["sigma_f90_parallax"], rtol=RTOL_PATHS)
    np.testing.assert_allclose(got["sigma_f90_pm"], 10 * exp["sigma_f90_parallax"], rtol=RTOL_PATHS)
    # the paper's prior ignores the colour: the two sigma columns only, as before
    _catalogue().to_csv(tmp_path / "c.csv", index=False)
    r = run("annotate", tmp_path / "c.csv", "--out", tmp_path / "paper.csv", "--paper")
    assert r.returncode == 0, r.stderr
    assert list(pd.read_csv(tmp_path / "paper.csv").columns)[-2:] == ["sigma_f90_parallax", "sigma_f90_pm"]
    # a colour column that is not numbers: one line, exit 2
    bad = _catalogue().astype({"bp_rp": object})
    bad.loc[3, "bp_rp"] = "blue"
    bad.to_csv(tmp_path / "bad.csv", index=False)
    r = run("annotate", tmp_path / "bad.csv", "--out", tmp_path / "bad_out.csv", "--run", colour_run)
    assert r.returncode == 2 and "bp_rp" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def _direct(obs, src, prior, normals):
    """Per source: the 5 x 5 normal equations of the library's design matrix, plus the
    prior N_p (Eq. 18) and N_p m in the right-hand side (Eqs. 11-12), solved by numpy."""
    out = {}
    for sid, grp in obs.groupby("source_id", sort=True):
        s = src.set_index("source_id").loc[sid]
        N0, b0, _ = normals(grp, s)
        l_deg, b_deg = galactic_from_icrs(s["ra"], s["dec"])
        g, c = s["phot_g_mean_mag"], s["bp_rp"]
        sig = prior.sigma_parallax_mas(l_deg, b_deg, g, c)
        w = np.array([0.0, 0.0, sig**-2, (10 * sig) ** -2, (10 * sig) ** -2])
        m = np.array([0.0, 0.0, prior.mean_parallax_mas(l_deg, b_deg, g, c), *prior.mean_pm_masyr(l_deg, b_deg, g, c)])
        N = N0[0] + np.diag(w)
        out[sid] = (np.linalg.solve(N, b0[0] + w * m), np.linalg.solve(N, b0[0]), m, np.linalg.inv(N))
    return out


def test_solve_with_the_mean_is_the_direct_solve(colour_mean_run, tmp_path, synth):
    obs, src = pd.read_csv(EXAMPLE / "observations.csv"), pd.read_csv(EXAMPLE / "sources.csv")
    src["bp_rp"] = np.linspace(-0.5, 3.0, len(src))
    src.loc[::3, "bp_rp"] = np.nan
    src.to_csv(tmp_path / "sources.csv", index=False)
    r = run("solve", EXAMPLE / "observations.csv", "--sources", tmp_path / "sources.csv", "--out",
            tmp_path / "sol.csv", "--run", colour_mean_run)
    assert r.returncode == 0, r.stderr
    got = pd.read_csv(tmp_path / "sol.csv", keep_default_na=False, na_values=[""]).set_index("source_id")
    prior = Prior.from_run(colour_mean_run)
    names = ["dalpha_star_mas", "ddelta_mas", "parallax_mas", "pmra_mas_yr", "pmdec_mas_yr"]
    ref = _direct(obs, src, prior, synth.source_normal_equations)
    assert len(ref) == len(got)
    shifted = 0
    for sid, (x, x_zero, m, cov) in ref.items():
        row = got.loc[sid]
        np.testing.assert_allclose(row[names].to_numpy(float), x, rtol=RTOL_SOLVE, atol=ATOL_MAS)
        np.testing.assert_allclose(row[["prior_mean_parallax_mas", "prior_mean_pmra_mas_yr",
                                        "prior_mean_pmdec_mas_yr"]].to_numpy(float), m[2:], rtol=1e-12)
        np.testing.assert_allclose(row[[n.replace("_mas", "_error_mas") for n in names]].to_numpy(float),
                                   np.sqrt(np.diag(cov)), rtol=RTOL_SOLVE)
        shifted += not np.allclose(x, x_zero, rtol=RTOL_SOLVE, atol=ATOL_MAS)
        colour = src.set_index("source_id").loc[sid, "bp_rp"]
        assert (row["prior_colour_bin"] == "colour_blind") == bool(np.isnan(colour))
    assert shifted == len(ref)  # the mean moved every solution


def test_solve_with_prior_mean_none_is_bit_identical():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(50, 8, 5))
    N0, b0 = normal_equations(A, rng.normal(size=(50, 8)))
    sig = rng.uniform(0.5, 3, 50)
    a, b = solve_with_prior(N0, b0, sig, 10.0), solve_with_prior(N0, b0, sig, 10.0, prior_mean=None)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.cov, b.cov)
    # a mean of zero changes nothing; the position components of the mean have no weight
    z = solve_with_prior(N0, b0, sig, 10.0, prior_mean=np.zeros(5))
    np.testing.assert_array_equal(z.x, a.x)
    m = np.array([5.0, -3.0, 1.0, 2.0, -4.0])
    p = solve_with_prior(N0, b0, sig, 10.0, prior_mean=m)
    q = solve_with_prior(N0, b0, sig, 10.0, prior_mean=m * [0, 0, 1, 1, 1])
    np.testing.assert_array_equal(p.x, q.x)
    with pytest.raises(ValueError, match="prior_mean"):
        solve_with_prior(N0, b0, sig, 10.0, prior_mean=np.zeros(4))
