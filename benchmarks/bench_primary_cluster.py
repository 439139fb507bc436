"""Benchmark: the driver's memory of a primary solution on a Dask cluster, data built on the
driver versus on the workers (experiments.primary_cluster).

For each star count, two runs in fresh processes, each with a LocalCluster of ``--workers``
worker processes (its scheduler in the driver's process, as ``execution=dask`` makes it):

* ``driver``: the stars drawn, put in sky order, their transits searched and the solver's
  blocks built in the driver (:func:`mcsweep.experiments.primary.local.prepare`), the chunks then
  scattered to the workers;
* ``cluster``: the stars drawn by a task and put in sky order on the workers
  (:func:`mcsweep.experiments.primary.sky.sky_partitions`), the transits, blocks and
  measurements made and kept there
  (:func:`mcsweep.experiments.primary.cluster.prepare_on_cluster`).

Then one solution (prior sigma_F90, ``--iterations`` PCG iterations) in each, its per-star
results read part by part (as the run writes them). Printed per run: measurements, the
driver's peak resident memory (``ru_maxrss``), wall time, and whether the two runs'
per-star results are the same bits; then the driver's growth between the two sizes per
star and per measurement, cluster against driver (the baseline, measured in the same run).

Stars: uniform over the sky, G uniform in 12-19 (the population does not matter for memory),
one year of the flown law, 20 % dead time, 3 h knots (the experiment's defaults).

The per-star results are read in parts of ``--part-stars`` stars (default 10000, so both
sizes hold several parts; a run's parts of 250000 stars bound the driver's part at some
25 MB whatever the size, :data:`mcsweep.experiments.primary.results.PART_STARS`).

Run: ``python benchmarks/bench_primary_cluster.py [--stars 30000 120000] [--iterations 5]
[--workers 2] [--part-stars 10000] [--chunk-stars 50000]`` (``--chunk-stars``: the solver's
chunks and the table's partitions, ``execution.chunk_stars``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def _stars(n: int, seed: int = 5):
    import numpy as np
    import pandas as pd

    rng = np.random.default_rng(seed)
    ra = rng.uniform(0.0, 360.0, n)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    return pd.DataFrame({"ra": ra, "dec": dec, "l": ra, "b": dec, "parallax": rng.uniform(0.1, 5.0, n),
                         "pmra": rng.normal(0.0, 10.0, n), "pmdec": rng.normal(0.0, 10.0, n),
                         "phot_g_mean_mag": rng.uniform(12.0, 19.0, n), "class_key": 1500})


def one(mode: str, n: int, iterations: int, workers: int, part_stars: int, chunk: int) -> dict:
    import functools

    import numpy as np
    from distributed import Client, LocalCluster

    from mcsweep.experiments.primary import experiment as P
    from mcsweep.experiments.primary.local import prepare
    from mcsweep.experiments.primary.prior_solution import solve_prior
    from mcsweep.experiments.primary.transits import transits_of
    from mcsweep.experiments.primary import results as primary_results
    from mcsweep.experiments.global_solution.classes import class_table, sky_order
    from mcsweep.experiments.primary.cluster import prepare_on_cluster
    from mcsweep.experiments.primary.sky import sky_partitions
    from mcsweep.command.validate import compose_config, to_config

    config = to_config(compose_config(["experiment=primary", f"experiment.primary.solver_max_iter={iterations}",
                                       "experiment.primary.allow_unconverged=true"]))
    settings = P.build_settings(config)
    primary_results.PART_STARS = part_stars
    digest = hashlib.sha256()
    t0 = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      env={"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}) as cluster, Client(cluster) as client:
        if mode == "driver":
            stars = class_table(_stars(n), 1500)
            stars = stars.iloc[sky_order(stars["ra"].to_numpy(), stars["dec"].to_numpy())].reset_index(drop=True)
            ra, dec = stars["ra"].to_numpy(), stars["dec"].to_numpy()
            parts = [transits_of((i, lo, ra[lo:lo + chunk], dec[lo:lo + chunk], settings.start_jd, settings.end_jd,
                                    settings.law))[1] for i, lo in enumerate(range(0, n, chunk))]
            tr = {k: np.concatenate([p[k] for p in parts]) for k in ("star", "t", "psi")}
            del parts
            data = prepare(settings, stars, tr)
            del tr, stars  # as the experiment's runner does: the solution's table (data.stars) has them
        else:
            sky, _ = sky_partitions(client, [(1500, functools.partial(client.submit, _stars, n, pure=False))], chunk)
            data = prepare_on_cluster(settings, sky, client, chunk_stars=chunk)
        res, _, extra, *_ = solve_prior(settings, data, "F90", dask_client=client, chunk_stars=chunk)
        for part in res.parts():  # part by part, as the run writes them
            for column in part.columns:
                digest.update(part[column].to_numpy().tobytes())
    digest = digest.hexdigest()[:16]
    return {"mode": mode, "stars": n, "measurements": data.n_measurements, "iterations": extra["iterations"],
            "seconds": time.perf_counter() - t0, "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "digest": digest}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stars", type=int, nargs=2, default=[30000, 120000])
    ap.add_argument("--iterations", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--part-stars", type=int, default=10000)
    ap.add_argument("--chunk-stars", type=int, default=50000)
    ap.add_argument("--one", nargs=2, metavar=("MODE", "STARS"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one[0], int(args.one[1]), args.iterations, args.workers, args.part_stars,
                                        args.chunk_stars)))
        return
    rows = {}
    print(f"one year, flown law, 3 h knots, {args.iterations} PCG iterations, LocalCluster of {args.workers} workers")
    print("    mode    stars  measurements  driver peak RSS [MB]  wall [s]  digest")
    for n in args.stars:
        for mode in ("driver", "cluster"):
            out = subprocess.run([sys.executable, __file__, "--one", mode, str(n), "--iterations", str(args.iterations),
                                  "--workers", str(args.workers), "--part-stars", str(args.part_stars),
                              "--chunk-stars", str(args.chunk_stars)], capture_output=True, text=True, check=True)
            r = json.loads(out.stdout.strip().splitlines()[-1])
            rows[mode, n] = r
            print(f"{mode:>8} {n:8d} {r['measurements']:13d} {r['peak_rss_mb']:21.0f} {r['seconds']:9.1f}  {r['digest']}")
        same = rows["driver", n]["digest"] == rows["cluster", n]["digest"]
        print(f"         per-star results of the two runs identical: {same}")
    lo, hi = args.stars
    dm = rows["driver", hi]["measurements"] - rows["driver", lo]["measurements"]
    for mode in ("driver", "cluster"):
        grow = (rows[mode, hi]["peak_rss_mb"] - rows[mode, lo]["peak_rss_mb"]) * 2**20
        print(f"{mode:>8}: driver growth {grow / (hi - lo):7.0f} bytes per star, {grow / dm:6.1f} bytes per measurement")
    g_d = rows["driver", hi]["peak_rss_mb"] - rows["driver", lo]["peak_rss_mb"]
    g_c = rows["cluster", hi]["peak_rss_mb"] - rows["cluster", lo]["peak_rss_mb"]
    print(f"ratio of the driver's growth, cluster / driver: {g_c / g_d:.2f}")


if __name__ == "__main__":
    main()
