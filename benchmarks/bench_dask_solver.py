"""Benchmark of the global solver on a Dask cluster whose workers keep the chunks
(mcsweep.solver.dask_resident).

Problem as ``bench_primary.py`` (random stars, the flown law's FoV transits over ``--days``,
a fraction ``--keep`` kept, AL + AC, noisy measurements, prior 1000 mas, R = 10 /yr), at two
star counts. Per size, on a LocalCluster of ``--workers`` worker processes (1 thread each):

* bytes sent to the workers and received from them per PCG iteration, counted by
  ``dask.sizeof`` on every argument and result of the passes
  (:class:`mcsweep.solver.dask_resident.DaskChunks`), against the bytes of the chunks sent
  once per solution (blocks and measurements);
* wall seconds per iteration, Dask against in-process;
* bit identity of the solution with the in-process one;
* the driver's peak resident memory (``ru_maxrss``, this process; the problem is built here).

Run: ``python benchmarks/bench_dask_solver.py [--stars 4000 16000] [--days 60] [--keep 0.5]
[--iterations 10] [--workers 2]``.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import resource  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from mcsweep.astrometry.solve import prior_diagonal  # noqa: E402
from mcsweep.solver import GlobalProblem, solve_global  # noqa: E402
from mcsweep.solver.dask_resident import DaskChunks  # noqa: E402
from mcsweep.solver.tasks import back_task, direction_task, forward_task  # noqa: E402

from bench_primary import data_for, make_obs  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stars", type=int, nargs="+", default=[4000, 16000])
    ap.add_argument("--days", type=float, default=60.0)
    ap.add_argument("--knot-days", type=float, default=1.0)
    ap.add_argument("--keep", type=float, default=0.5)
    ap.add_argument("--iterations", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--block-stars", type=int, default=1024)
    args = ap.parse_args()
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None,
                           env={"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"})
    client = Client(cluster)
    kw = dict(rtol=1e-14, update_tol_uas=0.0, max_iter=args.iterations, residuals=False)  # fixed iterations
    print(f"{args.days:g} days, keep {args.keep:g}, {args.iterations} PCG iterations, blocks of "
          f"{args.block_stars} stars, LocalCluster of {args.workers} workers")
    print("   stars  measurements  att.coef  chunks-sent-once  sent/iter  received/iter  s/iter dask  "
          "s/iter local  identical  driver peak RSS")
    for n in args.stars:
        obs, ra, dec, x, a, rng = make_obs(n, args.days, args.knot_days, args.keep)
        problem = GlobalProblem(obs, prior_diagonal(1000.0, 10.0), ra, dec, block_stars=args.block_stars)
        h = data_for(problem, x, a, rng)
        del obs
        t0 = time.perf_counter()
        ref = solve_global(problem, h, **kw)
        local = (time.perf_counter() - t0) / len(ref.history)
        ranges = problem.chunks(None)
        chunks = [(problem.blocks[lo:hi], [h[b.rows] for b in problem.blocks[lo:hi]]) for lo, hi in ranges]
        once = sum(sum(b.nbytes for b in bl) + sum(x.nbytes for x in hh) for bl, hh in chunks)
        res = DaskChunks.scatter(client, chunks)
        t0 = time.perf_counter()
        sol = solve_global(problem, h, resident_chunks=res, **kw)
        dask_s = (time.perf_counter() - t0) / len(sol.history)
        it_passes = res.passes - 2  # setup and residual passes excluded (one-off)
        same = np.array_equal(sol.x, ref.x) and np.array_equal(sol.attitude, ref.attitude)
        # per iteration = the iteration passes' bytes / iterations (one-off setup and residual passes apart)
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        sent, received = (v / len(sol.history) / 2**20 for v in res.bytes_per_call(forward_task, back_task, direction_task))
        print(f"{problem.n_stars:8d}  {problem.n_measurements:12d}  {problem.n_att:8d}  {once / 2**20:13.1f} MiB"
              f"  {sent:6.2f} MiB  {received:9.2f} MiB"
              f"  {dask_s:11.3f}  {local:12.3f}  {str(same):>9}  {rss:10.0f} MiB   ({it_passes} iteration passes)")
        del res, chunks
    client.close()
    cluster.close()


if __name__ == "__main__":
    main()
