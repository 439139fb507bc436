"""Benchmark of the secondary-solution experiment (``mcsweep experiment=secondary``; Sect. 4.1, Table 2).

For each class size it runs the real command line in a fresh process,

    mcsweep experiment=secondary experiment.secondary.class_size=N execution.n_jobs=J \
            execution.progress=false hydra.run.dir=OUT/nN

(three magnitude classes, so 3 N stars), and measures

* wall time of the whole command (start-up, population, transits and solutions in the
  workers, tables, report), and the per-stage times from its ``provenance.json``;
* peak memory: the sum of the resident set sizes of the command and all its worker
  processes, sampled every ``--interval`` s (an upper bound: pages shared between
  processes are counted once per process), and the largest single process.

It then fits ``time = a + b * stars`` and ``memory = c + d * stars`` over the sizes and
checks the issue's limits at the full scale (3 x 5e5 stars in <= 10 min and <= 8 GB on
2 cores). The load average is printed before and after: other jobs on the machine
slow the run down.

Run: ``python benchmarks/bench_secondary.py [--sizes 20000,100000,500000] [--n-jobs 2]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil

#: The issue's limits at full scale (3 x 5e5 stars, 2 cores).
MAX_WALL_S = 600.0
MAX_PEAK_GB = 8.0
FULL_CLASS_SIZE = 500_000
N_CLASSES = 3
GB = 1024.0**3


def _tree_rss(proc: psutil.Process) -> tuple[int, int]:
    """(sum of RSS, largest RSS) over a process and its descendants [bytes]."""
    total, largest = 0, 0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            rss = p.memory_info().rss
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            continue
        total += rss
        largest = max(largest, rss)
    return total, largest


def run_one(class_size: int, n_jobs: int, out: Path, interval: float, extra: list[str]) -> dict:
    run_dir = out / f"n{class_size}"
    cmd = [str(Path(sys.executable).parent / "mcsweep"), "experiment=secondary",
           f"experiment.secondary.class_size={class_size}", f"execution.n_jobs={n_jobs}",
           "execution.progress=false", f"hydra.run.dir={run_dir}", *extra]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    ps = psutil.Process(proc.pid)
    peak_total = peak_one = 0
    while proc.poll() is None:
        try:
            total, one = _tree_rss(ps)
        except psutil.NoSuchProcess:
            break
        peak_total, peak_one = max(peak_total, total), max(peak_one, one)
        time.sleep(interval)
    err = proc.communicate()[1]
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"mcsweep failed for class_size={class_size}:\n{err[-3000:]}")
    prov = json.loads((run_dir / "provenance.json").read_text())
    return {"class_size": class_size, "stars": N_CLASSES * class_size, "wall_s": wall,
            "peak_total_gb": peak_total / GB, "peak_process_gb": peak_one / GB,
            "stages": prov.get("timings_s", {}), "run_dir": run_dir}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="20000,100000,500000",
                    help="comma-separated class sizes (stars per magnitude class)")
    ap.add_argument("--n-jobs", type=int, default=2)
    ap.add_argument("--interval", type=float, default=0.1, help="memory sampling interval [s]")
    ap.add_argument("--out", default=None, help="directory for the run directories (default: a temporary one)")
    ap.add_argument("extra", nargs="*", help="further mcsweep overrides, e.g. execution.chunk_stars=20000")
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bench_secondary_"))
    print(f"cores: {os.cpu_count()}, n_jobs: {args.n_jobs}, load average before: "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}, runs in {out}")
    rows = []
    for n in sizes:
        r = run_one(n, args.n_jobs, out, args.interval, args.extra)
        rows.append(r)
        stages = ", ".join(f"{k} {v:.1f}" for k, v in r["stages"].items() if not k.startswith("previous:"))
        print(f"class_size {n:>8d} ({r['stars']:>8d} stars): wall {r['wall_s']:7.1f} s, peak memory "
              f"{r['peak_total_gb']:5.2f} GB (all processes), {r['peak_process_gb']:5.2f} GB (largest); "
              f"{r['stars'] / r['wall_s']:7.0f} stars/s; stages [s]: {stages}", flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    stars = np.array([r["stars"] for r in rows], float)
    if len(rows) >= 2:
        for key, unit in (("wall_s", "s"), ("peak_total_gb", "GB")):
            y = np.array([r[key] for r in rows])
            b, a = np.polyfit(stars, y, 1)
            print(f"fit {key} = {a:.3g} {unit} + {b * 1e6:.3g} {unit} per 1e6 stars")
    full = [r for r in rows if r["class_size"] == FULL_CLASS_SIZE]
    if full:
        r = full[0]
        ok = r["wall_s"] <= MAX_WALL_S and r["peak_total_gb"] <= MAX_PEAK_GB
        print(f"full scale ({r['stars']} stars): wall {r['wall_s']:.1f} s (limit {MAX_WALL_S:.0f}), peak "
              f"{r['peak_total_gb']:.2f} GB (limit {MAX_PEAK_GB:.0f}): {'PASS' if ok else 'FAIL'}")
        print((r["run_dir"] / "table2.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
