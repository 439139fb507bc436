"""mcsweep-prior annotate: every format, units kept, streaming, bad input (exit 2, nothing written)."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from astropy import units as u
from astropy.coordinates import SkyCoord
from astropy.table import Table

from mcsweep.prior import Prior
from mcsweep.prior.annotate import annotate_file

BIN = Path(sys.executable).parent
#: Fast rotation vs SkyCoord's transformation: rounding of ~1e-12 deg in the direction.
FRAME_RTOL = 1e-10
N = 257


def _stars(n=N, seed=1):
    rng = np.random.default_rng(seed)
    return Table({"source_id": np.arange(n, dtype=np.int64) + 10**15,
                  "ra": rng.uniform(0, 360, n) * u.deg,
                  "dec": np.degrees(np.arcsin(rng.uniform(-1, 1, n))) * u.deg,
                  "parallax": rng.uniform(0.1, 5, n) * u.mas,
                  "phot_g_mean_mag": rng.uniform(3, 22, n) * u.mag,
                  "note": np.array(["a", "bb"] * (n // 2) + ["c"] * (n % 2))})


def _expected(t):
    c = SkyCoord(ra=np.asarray(t["ra"], float) * u.deg, dec=np.asarray(t["dec"], float) * u.deg, frame="icrs")
    return Prior.paper().sigma_parallax(c, G=np.asarray(t["phot_g_mean_mag"], float)).value


def run(*args, umask=None):
    return subprocess.run([str(BIN / "mcsweep-prior"), *map(str, args)], capture_output=True, text=True,
                          timeout=300, preexec_fn=None if umask is None else (lambda: os.umask(umask)))


@pytest.mark.parametrize("suffix", [".fits", ".vot", ".ecsv", ".csv", ".parquet"])
def test_every_format_keeps_columns_and_units(tmp_path, suffix):
    t = _stars()
    src, out = tmp_path / f"in{suffix}", tmp_path / f"out{suffix}"
    if suffix == ".csv":
        t.to_pandas().to_csv(src, index=False)
    elif suffix == ".parquet":
        t.to_pandas().to_parquet(src, index=False)
    else:
        t.write(src, format={".fits": "fits", ".vot": "votable", ".ecsv": "ascii.ecsv"}[suffix])
    annotate_file(src, out, Prior.paper())
    if suffix in (".csv", ".parquet"):
        got = pd.read_csv(out) if suffix == ".csv" else pq.read_table(out).to_pandas()
        assert list(got.columns) == t.colnames + ["sigma_f90_parallax", "sigma_f90_pm"]
        np.testing.assert_array_equal(got["source_id"], t["source_id"])
        assert list(got["note"]) == list(t["note"])
        plx, pm = got["sigma_f90_parallax"].to_numpy(), got["sigma_f90_pm"].to_numpy()
    else:
        got = Table.read(out)
        assert got.colnames == t.colnames + ["sigma_f90_parallax", "sigma_f90_pm"]
        for name in ("ra", "dec", "parallax"):
            assert got[name].unit == t[name].unit
        assert got["sigma_f90_parallax"].unit == u.mas and got["sigma_f90_pm"].unit == u.mas / u.yr
        np.testing.assert_array_equal(got["source_id"], t["source_id"])
        plx, pm = np.asarray(got["sigma_f90_parallax"]), np.asarray(got["sigma_f90_pm"])
    np.testing.assert_allclose(plx, _expected(t), rtol=FRAME_RTOL, atol=0)
    np.testing.assert_allclose(pm, 10 * _expected(t), rtol=FRAME_RTOL, atol=0)


def test_galactic_columns_and_unit_conversion(tmp_path):
    t = _stars()
    c = SkyCoord(ra=t["ra"], dec=t["dec"]).galactic
    g = Table({"l": c.l.to(u.rad), "b": c.b.to(u.arcmin), "phot_g_mean_mag": t["phot_g_mean_mag"]})
    g.write(tmp_path / "gal.fits")
    annotate_file(tmp_path / "gal.fits", tmp_path / "out.ecsv", Prior.paper())
    np.testing.assert_allclose(Table.read(tmp_path / "out.ecsv")["sigma_f90_parallax"], _expected(t),
                               rtol=FRAME_RTOL, atol=0)


def test_parquet_streaming_is_batch_invariant(tmp_path):
    src = tmp_path / "in.parquet"
    _stars(n=1000).to_pandas().to_parquet(src, row_group_size=100)
    annotate_file(src, tmp_path / "a.parquet", Prior.paper(), batch_rows=37)
    annotate_file(src, tmp_path / "b.parquet", Prior.paper(), batch_rows=10**6)
    a, b = pq.read_table(tmp_path / "a.parquet"), pq.read_table(tmp_path / "b.parquet")
    assert a.equals(b)  # bit-identical whatever the batch size
    assert a.schema.field("sigma_f90_parallax").metadata[b"unit"] == b"mas"


def test_command_with_run_prior_and_paper(tmp_path):
    src = tmp_path / "in.csv"
    _stars().to_pandas().to_csv(src, index=False)
    r = run("annotate", src, "--out", tmp_path / "out.csv", "--paper")
    assert r.returncode == 0, r.stderr
    assert "257 rows annotated" in r.stderr
    got = pd.read_csv(tmp_path / "out.csv")
    np.testing.assert_allclose(got["sigma_f90_parallax"], _expected(_stars()), rtol=FRAME_RTOL, atol=0)
    assert not list(tmp_path.glob(".*.tmp"))


def _bad_cases(p):
    t = _stars().to_pandas()
    t.drop(columns=["phot_g_mean_mag"]).to_csv(p / "nog.csv", index=False)
    nan = t.copy()
    nan.loc[5, "ra"] = np.nan
    nan.to_parquet(p / "nan.parquet")
    km = _stars()
    km["ra"].unit = u.km
    km.write(p / "km.fits")
    (p / "junk.fits").write_bytes(b"not a fits file")
    (p / "table.dat").write_text("x")
    s = t.astype({"dec": object})
    s.loc[3, "dec"] = "north"
    s.to_csv(p / "str.csv", index=False)
    return [
        (["annotate", p / "nog.csv", "--out", p / "o1.csv"], "phot_g_mean_mag"),
        (["annotate", p / "nan.parquet", "--out", p / "o2.parquet"], "NaN"),
        (["annotate", p / "km.fits", "--out", p / "o3.fits"], "km"),
        (["annotate", p / "junk.fits", "--out", p / "o4.fits"], "junk.fits"),
        (["annotate", p / "table.dat", "--out", p / "o5.csv"], "suffix"),
        (["annotate", p / "missing.csv", "--out", p / "o6.csv"], "missing.csv"),
        (["annotate", p / "str.csv", "--out", p / "o7.csv"], "dec"),
        (["annotate", p / "nog.csv", "--out", p / "o8.csv", "--run", p], "coefficients.csv"),
        (["annotate", p / "nog.csv", "--out", p / "nodir" / "o9.csv"], "nodir"),
    ]


def test_bad_input_one_line_exit_2_nothing_written(tmp_path):
    for argv, needle in _bad_cases(tmp_path):
        before = set(tmp_path.rglob("*"))
        r = run(*argv)
        assert r.returncode == 2, (argv, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr, (argv, r.stderr)
        assert set(tmp_path.rglob("*")) == before, argv  # no output, no temporary left


@pytest.mark.parametrize("suffix", [".fits", ".vot", ".ecsv", ".csv", ".parquet"])
def test_command_writes_every_output_format(tmp_path, suffix):
    # Through the command: its output goes to a temporary file that already exists (empty)
    # before the writer runs; astropy's writers refuse that unless told to overwrite.
    t = _stars()
    src, out = tmp_path / "in.csv", tmp_path / f"out{suffix}"
    t.to_pandas().to_csv(src, index=False)
    r = run("annotate", src, "--out", out, "--paper", umask=0o027)
    assert r.returncode == 0, r.stderr[-2000:]
    # Readable by the user's group, as a file the user created normally (not the temporary's 0600).
    assert out.stat().st_mode & 0o777 == 0o640
    got = Table.read(out) if suffix != ".csv" else Table.from_pandas(pd.read_csv(out))
    np.testing.assert_allclose(np.asarray(got["sigma_f90_parallax"], float), _expected(t), rtol=FRAME_RTOL, atol=0)
    if suffix in (".fits", ".vot", ".ecsv", ".parquet"):
        assert got["sigma_f90_parallax"].unit == u.mas
    assert [p.name for p in tmp_path.iterdir()] and not list(tmp_path.glob(".*.tmp"))


#: ``mcsweep-prior annotate`` whose write stops after the annotated rows are on disk (name of the
#: temporary to READY, then asleep), so that the test can SIGKILL it mid-write.
_STALLED_ANNOTATE = """
import sys, time
from pathlib import Path
import mcsweep.prior.annotate as annotate
from mcsweep import prior_cli
real, ready = annotate.annotate_file, Path(sys.argv[1])
def stalled(src, dst, *a, **k):
    real(src, dst, *a, **k)
    ready.write_text(str(dst))
    time.sleep(600)
annotate.annotate_file = stalled
prior_cli.main(sys.argv[2:])
"""


def test_a_killed_annotate_leaves_a_temporary_that_the_next_one_removes(tmp_path):
    import signal
    import time

    src, out, side = tmp_path / "in.csv", tmp_path / "out.csv", tmp_path / "side"
    side.mkdir()
    _stars().to_pandas().to_csv(src, index=False)
    ready = side / "ready"
    proc = subprocess.Popen([sys.executable, "-c", _STALLED_ANNOTATE, str(ready), "annotate", str(src),
                             "--out", str(out), "--paper"])
    deadline = time.monotonic() + 120
    while not ready.exists() or not ready.read_text():
        assert proc.poll() is None and time.monotonic() < deadline, "annotate did not start its write"
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    assert proc.wait(timeout=60) == -signal.SIGKILL
    stale = Path(ready.read_text())
    assert stale.parent == tmp_path and stale.name.startswith(".out.csv.") and stale.stat().st_size > 0
    other = tmp_path / ".out.parquet.k1ll3d00.tmp"  # another output's, left by another killed run
    other.write_bytes(b"partial")
    r = run("annotate", src, "--out", out, "--paper")
    assert r.returncode == 0, r.stderr
    assert not stale.exists() and other.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([other.name, "in.csv", "out.csv", "side"])
