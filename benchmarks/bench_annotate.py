"""Throughput and memory of ``mcsweep-prior annotate`` on Parquet catalogues.

Writes a Gaia-like Parquet file (source_id, ra, dec, parallax, pmra, pmdec,
phot_g_mean_mag, bp_rp: 8 columns), then in the same run measures

* baseline: a plain pyarrow copy of the file in the same batches (read + write, no
  computation): what any streaming tool must pay;
* annotate: the library path (:func:`mcsweep.prior.annotate.annotate_file`);
* peak resident memory of the ``mcsweep-prior annotate`` command on N and 4 N rows,
  each in its own process (constant memory means the two peaks are about equal).

Timings are the best of ``--repeat`` runs; the machine may be shared, so the ratio to
the baseline is the number to compare between machines.

    python benchmarks/bench_annotate.py --rows 2000000
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mcsweep.prior import Prior
from mcsweep.prior.annotate import BATCH_ROWS, annotate_file


def make_catalogue(path: Path, n: int, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    with pq.ParquetWriter(path, pa.schema([(c, pa.int64() if c == "source_id" else pa.float64()) for c in
                                           ("source_id", "ra", "dec", "parallax", "pmra", "pmdec",
                                            "phot_g_mean_mag", "bp_rp")])) as w:
        for start in range(0, n, BATCH_ROWS):
            m = min(BATCH_ROWS, n - start)
            w.write_table(pa.table({
                "source_id": np.arange(start, start + m, dtype=np.int64),
                "ra": rng.uniform(0, 360, m), "dec": np.degrees(np.arcsin(rng.uniform(-1, 1, m))),
                "parallax": rng.exponential(1.0, m), "pmra": rng.normal(0, 5, m), "pmdec": rng.normal(0, 5, m),
                "phot_g_mean_mag": rng.uniform(6, 21, m), "bp_rp": rng.normal(1, 0.4, m)}))


def baseline_copy(src: Path, dst: Path) -> None:
    pf = pq.ParquetFile(src, pre_buffer=False)  # as annotate reads it
    with pq.ParquetWriter(dst, pf.schema_arrow) as w:
        for batch in pf.iter_batches(batch_size=BATCH_ROWS):
            w.write_batch(batch)


def best_time(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def peak_rss_mb(args: list[str]) -> float:
    code = ("import resource, sys; from mcsweep.prior_cli import main; rc = main(sys.argv[1:]); "
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")
    r = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, check=True)
    return int(r.stdout.strip().splitlines()[-1]) / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    n = args.rows
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src, big = tmp / "cat.parquet", tmp / "cat4.parquet"
        make_catalogue(src, n)
        prior = Prior.paper()
        t_base = best_time(lambda: baseline_copy(src, tmp / "copy.parquet"), args.repeat)
        t_ann = best_time(lambda: annotate_file(src, tmp / "out.parquet", prior), args.repeat)
        make_catalogue(big, 4 * n, seed=1)
        rss1 = peak_rss_mb(["annotate", str(src), "--out", str(tmp / "o1.parquet")])
        rss4 = peak_rss_mb(["annotate", str(big), "--out", str(tmp / "o4.parquet")])
    print("machine shared with other jobs: compare ratios, not absolute rates")
    print(f"rows                         {n}")
    print(f"baseline pyarrow copy        {t_base:.3f} s  ({n / t_base / 1e6:.2f} M rows/s)")
    print(f"annotate (library)           {t_ann:.3f} s  ({n / t_ann / 1e6:.2f} M rows/s)")
    print(f"ratio annotate / baseline    {t_ann / t_base:.2f}")
    print(f"peak RSS command, {n} rows   {rss1:.0f} MB")
    print(f"peak RSS command, {4 * n} rows  {rss4:.0f} MB  (ratio {rss4 / rss1:.2f}; 1 = constant memory)")


if __name__ == "__main__":
    main()
