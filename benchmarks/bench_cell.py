"""Benchmark of one pencil-beam cell's prior search: the batched 5 x 5 solver vs the prior scan.

Both evaluations run in this process on the same normal equations (the Table 1
direction, G = 14.5-15.5, all observation cases, the default 41-prior grid):

* ``old``: every star and prior solved as a 5 x 5 system in one batch
  (``solve_with_prior`` on the normal equations tiled once per prior), followed by the
  cell statistics -- the evaluation of ``prior_curve`` before the prior scan;
* ``new``: what a sweep cell evaluates now (``mcsweep.astrometry.prior_scan``: one
  reduction per star, the fused inside test at every prior of the grid, the
  percentile and semi-major statistics at one prior, sigma_F90; ``cell.grid_statistics=false``);
* ``new+stats``: the same with the statistics at every prior of the grid (the showcase
  cell of Figs. 1 and 3, or ``cell.grid_statistics=true``).

Checks that ``new`` gives the same inside and valid counts as ``old`` at every prior
and prints the number of differing counts (0 expected). Prints seconds per star (best
of ``--repeat``, CPU time), the ratios old/new, and the peak memory of each evaluation
(``tracemalloc``, numpy buffers included). The machine may be shared with other jobs:
compare the ratios, not the absolute times.

Run: ``python benchmarks/bench_cell.py [--stars 2000 20000] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402
import tracemalloc  # noqa: E402

import numpy as np  # noqa: E402

from mcsweep.astrometry.confidence import chi2_threshold, ellipse_semi_axes, mahalanobis_sq  # noqa: E402
from mcsweep.astrometry.solve import solve_with_prior  # noqa: E402
from mcsweep.experiments.f90_sweep import pencil_beam as pb  # noqa: E402
from mcsweep.population import GalaxyModel  # noqa: E402
from mcsweep.experiments.f90_sweep.cells import sky_directions  # noqa: E402
from mcsweep.experiments.f90_sweep.runner import build_settings, direction_transits  # noqa: E402
from mcsweep.experiments.f90_sweep.conf import SkyConf  # noqa: E402
from mcsweep.command.validate import compose_config, to_config  # noqa: E402


def old_curve(n0, b0, priors, s):
    """The batched evaluation of prior_curve before the prior scan (for timing only)."""
    m, n = len(priors), n0.shape[0]
    sol = solve_with_prior(np.tile(n0, (m, 1, 1)), np.tile(b0, (m, 1)), np.repeat(priors, n), ratio_R=s.ratio_R)
    dpos, cov2 = np.ascontiguousarray(sol.x[:, :2]), np.ascontiguousarray(sol.cov[:, :2, :2])
    q = mahalanobis_sq(dpos, cov2).reshape(m, n)
    valid = np.isfinite(q)
    frac = np.sum((q < chi2_threshold(s.confidence, 2)) & valid, axis=1) / np.maximum(valid.sum(axis=1), 1)
    err = np.hypot(dpos[:, 0], dpos[:, 1]).reshape(m, n)
    semi = ellipse_semi_axes(cov2, s.confidence)[0].reshape(m, n)
    return frac, np.percentile(err, 90.0, axis=1), np.median(semi, axis=1)


def new_curve(n0, b0, priors, s):
    # Grid fractions without statistics, then the statistics at the crossing (as run_cell).
    scan = pb.prior_scan(n0, b0, s.ratio_R)
    table = pb.scan_arrays(scan, priors, s, statistics=False)[0]
    f90 = pb.sigma_f90_from_curve(priors, table["fraction_inside"], s.confidence)[0]
    pb.scan_arrays(scan, [f90 if np.isfinite(f90) else priors[-1]], s, statistics=True)
    return table


def new_curve_stats(n0, b0, priors, s):
    return pb.prior_curve(n0, b0, priors, s, statistics=True)


def _measure(fn, normals, priors, s, repeat):
    best = np.inf
    for _ in range(repeat):
        t = time.process_time()
        for n0, b0 in normals:
            fn(n0, b0, priors, s)
        best = min(best, time.process_time() - t)
    tracemalloc.start()
    for n0, b0 in normals:
        fn(n0, b0, priors, s)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return best, peak


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stars", type=int, nargs="+", default=[2000, 20000])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    config = to_config(compose_config(["sky=single", "magnitudes=g15"]))
    s = build_settings(config)
    priors = np.asarray(s.prior_grid_mas)
    d = sky_directions(SkyConf(name="t1", kind="list", frame="icrs", directions=[[157.5, 0.0]]))[0]
    transits = direction_transits(config, [d])[d.index]
    print("Shared machine: absolute times are noisy; the ratio is measured in one run.")
    print(f"{'stars':>7} {'old us/star':>12} {'new us/star':>12} {'ratio':>6} {'new+stats':>10} {'ratio':>6} "
          f"{'old MB':>7} {'new MB':>7} {'+stats MB':>9} {'count diffs':>11}")
    for n in args.stars:
        stars = GalaxyModel().sample_cone(d.l_deg, d.b_deg, 1.0, 14.5, 15.5, np.random.default_rng(1),
                                          max_stars=n, min_draw=n)
        normals = []
        for groups in s.cases.values():
            geom = pb.case_geometry(transits, tuple(groups))
            normals.append(pb.cell_normals(geom, d.ra_deg, d.dec_deg, stars, s, np.random.default_rng(2)).matrices())
        t_old, m_old = _measure(old_curve, normals, priors, s, args.repeat)
        t_new, m_new = _measure(new_curve, normals, priors, s, args.repeat)
        t_all, m_all = _measure(new_curve_stats, normals, priors, s, args.repeat)
        diffs = 0
        for n0, b0 in normals:
            ref = pb.prior_curve(n0, b0, priors, s, method="direct")
            new = new_curve(n0, b0, priors, s)
            diffs += int(np.sum(ref["n_inside"] != new["n_inside"]) + np.sum(ref["n_valid"] != new["n_valid"]))
        k = len(stars)
        print(f"{k:7d} {1e6 * t_old / k:12.2f} {1e6 * t_new / k:12.2f} {t_old / t_new:6.1f} "
              f"{1e6 * t_all / k:10.2f} {t_old / t_all:6.1f} "
              f"{m_old / 1e6:7.1f} {m_new / 1e6:7.1f} {m_all / 1e6:9.1f} {diffs:11d}")


if __name__ == "__main__":
    main()
