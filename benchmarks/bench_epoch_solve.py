"""Benchmark of ``mcsweep-prior solve`` on Gaia DR4 epoch astrometry, against ESA's gaiasupdate.

The vendored sample (10 real sources, 49-177 FoV transits each, ~98 on average) is replicated
with new source_ids into a Parquet file of ``--sources`` sources (row groups of 50 000
transits, written piece by piece), with a sources table to match. The command solves it
(5p, the paper's prior, every output column) in a subprocess, once per ``--jobs`` value, and
this prints sources per second of wall time and the command's peak memory (resident set,
its workers included). Two sizes are run (``--sources`` and 4 times fewer) so that the peak
memory shows whether it is flat in the number of sources.

Baseline, measured in the same run: gaiasupdate's own source update
(``GaiaEpochAstrometryCu9.supdate(df, source_id, '5p_single_source')``, one source at a
time, as its API goes), timed on the sample's sources. gaiasupdate pins pandas < 3, so it
runs in its own interpreter: ``--gaiasupdate-python PATH`` (a virtualenv with
``pip install gaiasupdate==0.1.2``); without it the ratio is not printed. Target: >= 100 x
gaiasupdate per source.

Run: ``python benchmarks/bench_epoch_solve.py [--sources 10000] [--jobs 1 2]
[--gaiasupdate-python /tmp/gsenv/bin/python]``.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from importlib.resources import files
from pathlib import Path

import pandas as pd

SAMPLE = files("mcsweep") / "data" / "epoch_astrometry"
#: Target: sources per second against gaiasupdate's, one core each.
REQUIRED_RATIO = 100.0
ROW_GROUP = 50_000

GAIASUPDATE_TIMER = r"""
import sys, time, warnings, logging
warnings.simplefilter("ignore"); logging.disable(logging.CRITICAL)
import pandas as pd
from gaiasupdate.epoch_astrometry import GaiaEpochAstrometryCu9
df = pd.read_parquet(sys.argv[1])
ids = sorted(df["sourceId"].unique())
t = time.perf_counter()
for sid in ids:
    GaiaEpochAstrometryCu9.supdate(df[df["sourceId"] == sid], sid, "5p_single_source")
print(len(ids), time.perf_counter() - t)
"""


def build(n_sources: int, folder: Path) -> tuple[Path, Path]:
    """The sample replicated to ``n_sources`` sources (Parquet) and its sources table (CSV)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    df = pd.read_parquet(str(SAMPLE / "sample_epoch_astrometry.parquet"))
    src = pd.read_csv(str(SAMPLE / "sample_sources.csv"), comment="#")
    per = df["sourceId"].nunique()
    reps = -(-n_sources // per)
    epoch, sources = folder / f"epochs_{n_sources}.parquet", folder / f"sources_{n_sources}.csv"
    base = pa.Table.from_pandas(df, preserve_index=False)
    ids = df["sourceId"].to_numpy()
    with pq.ParquetWriter(epoch, base.schema) as w:
        for r in range(reps):
            t = base.set_column(base.schema.get_field_index("sourceId"), "sourceId",
                                pa.array(ids + r * per, type=pa.int64()))
            w.write_table(t, row_group_size=ROW_GROUP)
    rows = [src.assign(source_id=src["source_id"] + r * per) for r in range(reps)]
    pd.concat(rows, ignore_index=True)[["source_id", "ra", "dec", "phot_g_mean_mag"]].to_csv(sources, index=False)
    return epoch, sources


def solve(epoch: Path, sources: Path, jobs: int, out: Path) -> tuple[float, float]:
    """(wall seconds, peak resident MB) of the command on one input."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    cmd = [str(Path(sys.executable).parent / "mcsweep-prior"), "solve", str(epoch), "--sources", str(sources),
           "--out", str(out), "--jobs", str(jobs)]
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t
    if r.returncode:
        raise SystemExit(r.stderr)
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return dt, max(peak, before) / 1024


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", type=int, default=10_000)
    ap.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--gaiasupdate-python", default=None)
    args = ap.parse_args(argv)
    os.environ.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        theirs = None
        if args.gaiasupdate_python:
            r = subprocess.run([args.gaiasupdate_python, "-c", GAIASUPDATE_TIMER,
                                str(SAMPLE / "sample_epoch_astrometry.parquet")], capture_output=True, text=True)
            if r.returncode:
                raise SystemExit(r.stderr)
            n, dt = map(float, r.stdout.split()[-2:])
            theirs = n / dt
            print(f"gaiasupdate 0.1.2: {int(n)} sources in {dt:.2f} s: {theirs:.1f} sources/s (one core)")
        timings: dict[int, list[tuple[int, float]]] = {j: [] for j in args.jobs}
        for n_src in (args.sources // 4, args.sources):
            epoch, sources = build(n_src, tmp)
            size = epoch.stat().st_size / 1e6
            for jobs in args.jobs:
                # A fresh interpreter per measurement: RUSAGE_CHILDREN keeps the largest child's peak.
                code = ("import sys; sys.path.insert(0, %r); import bench_epoch_solve as b; from pathlib import Path; "
                        "print(*b.solve(Path(%r), Path(%r), %d, Path(%r)))"
                        % (str(Path(__file__).parent), str(epoch), str(sources), jobs, str(tmp / "out.parquet")))
                r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
                if r.returncode:
                    raise SystemExit(r.stderr)
                dt, peak = map(float, r.stdout.split())
                n_out = len(pd.read_parquet(tmp / "out.parquet", columns=["source_id"]))
                rate = n_out / dt
                ratio = f", {rate / theirs:.0f} x gaiasupdate" if theirs else ""
                timings[jobs].append((n_out, dt))
                print(f"{n_out} sources ({size:.0f} MB Parquet), --jobs {jobs}: {dt:.2f} s wall, "
                      f"{rate:.0f} sources/s{ratio}; peak memory {peak:.0f} MB")
        # Start-up (imports, the workers' start) is a fixed cost: the rate per source is the
        # slope between the two sizes.
        for jobs, ((n1, t1), (n2, t2)) in timings.items():
            rate = (n2 - n1) / (t2 - t1)
            ratio = f" = {rate / theirs:.0f} x gaiasupdate (target >= {REQUIRED_RATIO:.0f})" if theirs else ""
            print(f"--jobs {jobs}: {rate:.0f} sources/s per added source (start-up {t1 - n1 / rate:.2f} s){ratio}")
        if theirs is None:
            print("gaiasupdate not measured (--gaiasupdate-python not given): no ratio")


if __name__ == "__main__":
    main()
