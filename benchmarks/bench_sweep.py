"""Benchmark of whole sweeps against a baseline commit, side by side in one run.

For each sweep (``--sweeps``: the default ``mcsweep``, ``prior_model=colour``,
``prior_model=colour_mean``) this runs the baseline commit (``--baseline``, checked out
with ``git worktree`` into a temporary folder and run from there with the same virtualenv)
and the working tree, one after the other, each in its own process, and prints:

* wall time and the provenance's stage times (start-up = wall minus the stages), the
  ratios baseline / now;
* peak memory (the largest resident set of the command's processes, ``ru_maxrss``);
* whether the result tables (``cells.parquet``, ``f90_cells.csv``, ``coefficients.csv``,
  ``rms_dex.csv``) are byte-identical.

The machine may be shared: compare the ratios of one run, not absolute times.

Run: ``python benchmarks/bench_sweep.py [--baseline ee96f88] [--sweeps default colour colour_mean]
[--keep DIR]``.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TABLES = ("cells.parquet", "f90_cells.csv", "coefficients.csv", "rms_dex.csv")
SWEEPS = {"default": [], "colour": ["prior_model=colour"], "colour_mean": ["prior_model=colour_mean"]}

ENTRY = "from mcsweep import cli; getattr(cli, 'console_main', cli.main)()"

RUNNER = r"""
import json, resource, subprocess, sys, time
cmd, env = json.loads(sys.argv[1]), json.loads(sys.argv[2])
t = time.perf_counter()
r = subprocess.run(cmd, env=env, capture_output=True, text=True)
dt = time.perf_counter() - t
if r.returncode:
    sys.exit(r.stderr[-2000:])
print(json.dumps({"wall": dt, "peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}))
"""


def run(src: Path, overrides: list[str], out: Path) -> dict:
    """Wall time, peak memory and stage times of one sweep with the package at ``src``."""
    env = dict(os.environ, PYTHONPATH=str(src), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    # The command's entry point as the checkout at ``src`` defines it (the installed script
    # names the working tree's, which an older baseline may not have).
    cmd = [sys.executable, "-c", ENTRY, *overrides, f"hydra.run.dir={out}"]
    # A fresh interpreter per sweep: RUSAGE_CHILDREN then holds that sweep's peak alone.
    r = subprocess.run([sys.executable, "-c", RUNNER, json.dumps(cmd), json.dumps(env)], capture_output=True,
                       text=True)
    if r.returncode:
        raise SystemExit(r.stderr)
    res = json.loads(r.stdout.strip().splitlines()[-1])
    res["stages"] = json.loads((out / "provenance.json").read_text())["timings_s"]
    res["stages"]["start-up and rest"] = res["wall"] - sum(res["stages"].values())
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="ee96f88")
    ap.add_argument("--sweeps", nargs="+", default=["default"], choices=list(SWEEPS),
                    help="which sweeps (the colour ones take several minutes each)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the run directories here")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    work = args.keep or tmp
    base_tree = tmp / "baseline"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(base_tree), args.baseline],
                   check=True)
    try:
        for name in args.sweeps:
            res = {}
            for label, src in (("baseline", base_tree / "src"), ("now", ROOT / "src")):
                res[label] = run(src, SWEEPS[name], work / f"{name}_{label}")
            b, n = res["baseline"], res["now"]
            same = all(filecmp.cmp(work / f"{name}_baseline" / f, work / f"{name}_now" / f, shallow=False)
                       for f in TABLES if (work / f"{name}_baseline" / f).exists())
            print(f"\n{name} sweep ({' '.join(SWEEPS[name]) or 'defaults'}), baseline {args.baseline} vs working tree")
            print(f"{'stage':<20}{'baseline s':>12}{'now s':>10}{'ratio':>8}")
            for stage in b["stages"]:
                sb, sn = b["stages"][stage], n["stages"].get(stage, float("nan"))
                print(f"{stage:<20}{sb:>12.2f}{sn:>10.2f}{sb / sn if sn else float('nan'):>8.2f}")
            print(f"{'wall':<20}{b['wall']:>12.2f}{n['wall']:>10.2f}{b['wall'] / n['wall']:>8.2f}")
            print(f"peak memory MB: baseline {b['peak_mb']:.0f}, now {n['peak_mb']:.0f}; "
                  f"result tables byte-identical: {'yes' if same else 'NO'}")
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_tree)], check=False)


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"\nbenchmark wall time {time.perf_counter() - t0:.0f} s")
