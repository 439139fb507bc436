"""mcsweep-prior solve: reproduces the astrometry stage's solutions on the example file."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mcsweep.astrometry.confidence import ellipse_position_angle_deg
from mcsweep.astrometry.solve import solve_no_prior, solve_position_only, solve_with_prior

BIN = Path(sys.executable).parent
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "prior_solve"
#: One source at a time (reference below) vs all sources batched: the same arithmetic in
#: a different memory layout; a 5 x 5 Cholesky of condition <= 1e8 loses ~8 digits at most.
RTOL_PATHS = 1e-7
ATOL_MAS = 1e-9  # mas, for parameters that are 0 to rounding


def run(*args):
    return subprocess.run([str(BIN / "mcsweep-prior"), *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def paper_sigma(ra, dec, g):
    from astropy import units as u
    from astropy.coordinates import SkyCoord

    c = SkyCoord(ra=ra * u.deg, dec=dec * u.deg).galactic
    g = min(g, 20.0)
    s0 = 2.187 - 0.2547 * g + 0.006382 * g**2
    s1 = 0.114 - 0.0579 * g + 0.01369 * g**2 - 0.000506 * g**3
    s2 = 0.031 - 0.0062 * g
    return 10 ** (s0 + s1 * abs(np.sin(c.b.rad)) + s2 * np.cos(c.b.rad) * np.cos(c.l.rad))


def reference_solutions(obs, src, factor, normals):
    """Source by source, straight from the library's astrometry stage (``normals``: the
    conftest's ``source_normal_equations``)."""
    rows = []
    for sid, grp in obs.groupby("source_id", sort=True):
        s = src.set_index("source_id").loc[sid]
        k = len(grp)
        N0, b0, ep = normals(grp, s)
        sig = factor * paper_sigma(s["ra"], s["dec"], s["phot_g_mean_mag"])
        rows.append((sid, k, ep[0], sig, solve_with_prior(N0, b0, sig, 10.0), solve_position_only(N0, b0),
                     solve_no_prior(N0, b0)))
    return rows


@pytest.mark.parametrize("factor", [1.0, 10.0])
def test_command_reproduces_the_library_on_the_example(tmp_path, factor, synth):
    out = tmp_path / "sol.csv"
    r = run("solve", EXAMPLE / "observations.csv", "--sources", EXAMPLE / "sources.csv", "--out", out,
            "--paper", "--factor", factor)
    assert r.returncode == 0, r.stderr
    got = pd.read_csv(out).set_index("source_id")
    obs, src = pd.read_csv(EXAMPLE / "observations.csv"), pd.read_csv(EXAMPLE / "sources.csv")
    ref = reference_solutions(obs, src, factor, synth.source_normal_equations)
    assert len(got) == len(ref) == src["source_id"].isin(obs["source_id"]).sum()
    names = ["dalpha_star_mas", "ddelta_mas", "parallax_mas", "pmra_mas_yr", "pmdec_mas_yr"]
    for sid, k, ep, sig, wp, two, free in ref:
        row = got.loc[sid]
        assert row["n_transits"] == k
        assert row["reference_epoch_tcb_jd"] == pytest.approx(ep, rel=1e-15)
        assert row["sigma_prior_parallax_mas"] == pytest.approx(sig, rel=1e-10)
        np.testing.assert_allclose(row[names].to_numpy(float), wp.x[0], rtol=RTOL_PATHS, atol=ATOL_MAS)
        np.testing.assert_allclose(row[[n.replace("_mas", "_error_mas") for n in names]].to_numpy(float),
                                   np.sqrt(np.diag(wp.cov[0])), rtol=RTOL_PATHS)
        np.testing.assert_allclose(row[["two_param_dalpha_star_mas", "two_param_ddelta_mas"]].to_numpy(float),
                                   two.x[0, :2], rtol=RTOL_PATHS, atol=ATOL_MAS)
        assert bool(row["no_prior_ok"]) == bool(free.ok[0])
        if free.ok[0]:
            np.testing.assert_allclose(row[["no_prior_" + n for n in names]].to_numpy(float), free.x[0],
                                       rtol=RTOL_PATHS, atol=ATOL_MAS)
        # P = 0.9 ellipse: semi-axes sqrt(-2 ln(1 - P) lambda) of the position covariance
        lam = np.linalg.eigvalsh(wp.cov[0, :2, :2])
        np.testing.assert_allclose([row["ellipse_semi_major_mas"], row["ellipse_semi_minor_mas"]],
                                   np.sqrt(-2 * np.log(0.1) * lam[::-1]), rtol=RTOL_PATHS)


def test_ellipse_position_angle_from_north_through_east():
    def cov(pa_deg, major=4.0, minor=1.0):
        t = np.radians(pa_deg)
        v = np.array([np.sin(t), np.cos(t)])  # (east, north) of the major axis
        w = np.array([np.cos(t), -np.sin(t)])
        return major * np.outer(v, v) + minor * np.outer(w, w)

    pas = [0.0, 30.0, 90.0, 135.0, 179.0]
    got = ellipse_position_angle_deg(np.stack([cov(p) for p in pas]))
    np.testing.assert_allclose(got, pas, atol=1e-12)


def test_bad_input_one_line_exit_2_nothing_written(tmp_path):
    obs = pd.read_csv(EXAMPLE / "observations.csv")
    obs.drop(columns=["al_sigma_mas"]).to_csv(tmp_path / "nosig.csv", index=False)
    nan = obs.copy()
    nan.loc[2, "al_residual_mas"] = np.nan
    nan.to_csv(tmp_path / "nan.csv", index=False)
    neg = obs.copy()
    neg.loc[0, "al_sigma_mas"] = -1.0
    neg.to_csv(tmp_path / "neg.csv", index=False)
    src = pd.read_csv(EXAMPLE / "sources.csv")
    src.iloc[1:].to_csv(tmp_path / "src_short.csv", index=False)
    obs.drop(columns=["ac_sigma_mas"]).to_csv(tmp_path / "half_ac.csv", index=False)
    (tmp_path / "junk.parquet").write_bytes(b"PAR1 not really")
    good_src = EXAMPLE / "sources.csv"
    cases = [
        (["solve", tmp_path / "nosig.csv", "--sources", good_src], "al_sigma_mas"),
        (["solve", tmp_path / "nan.csv", "--sources", good_src], "NaN"),
        (["solve", tmp_path / "neg.csv", "--sources", good_src], "al_sigma_mas"),
        (["solve", EXAMPLE / "observations.csv", "--sources", tmp_path / "src_short.csv"], "source_id"),
        (["solve", tmp_path / "half_ac.csv", "--sources", good_src], "ac_residual_mas"),
        (["solve", tmp_path / "junk.parquet", "--sources", good_src], "junk.parquet"),
        (["solve", EXAMPLE / "observations.csv"], "phot_g_mean_mag"),
        (["solve", EXAMPLE / "observations.csv", "--sources", good_src, "--run", tmp_path], "coefficients"),
        (["solve", EXAMPLE / "observations.csv", "--sources", good_src, "--factor", "-2"], "factor"),
        (["solve", EXAMPLE / "observations.csv", "--sources", good_src, "--confidence", "1.5"], "1.5"),
        (["solve", EXAMPLE / "observations.csv", "--sources", good_src, "--reference-epoch", "soon"], "soon"),
    ]
    for argv, needle in cases:
        before = set(tmp_path.rglob("*"))
        r = run(*argv, "--out", tmp_path / "out.csv")
        assert r.returncode == 2, (argv, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr, (argv, r.stderr)
        assert set(tmp_path.rglob("*")) == before, argv
