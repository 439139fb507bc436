"""Benchmark of the global (primary) solver: PCG against a direct sparse solve, and scaling.

On the same small system (random stars over the sky, the flown law's FoV transits over a
few days, AL + AC, noisy measurements, the F90-like prior of 1 mas, Eq. 18), in the same
run:

* PCG (:func:`mcsweep.solver.solve_global`, AGIS block preconditioner, Bombrun et al.
  2012): CPU seconds, iterations, CPU seconds per iteration;
* direct: the same normal equations from the explicit sparse design (scipy.sparse) with
  the frame penalty as a bordered system, solved by ``scipy.sparse.linalg.spsolve``;
  the ratio direct / PCG and the relative difference of the two solutions;
* ``scipy.sparse.linalg.lsqr`` on the (weighted) design of the same system, for the
  issue's reference ratio;
* scaling: PCG CPU seconds per iteration at 1x, 2x and 4x the stars;
* peak memory (``ru_maxrss`` of this process).

Times are CPU seconds of this process (``time.process_time``): the machine is shared,
so only ratios measured in this run mean anything.

Run: ``python benchmarks/bench_primary.py [--stars 20000] [--days 10] [--knot-days 0.5]``.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import resource  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from scipy.sparse.linalg import lsqr, spsolve  # noqa: E402

from mcsweep.astrometry.noise import NoiseModel  # noqa: E402
from mcsweep.astrometry.solve import prior_diagonal  # noqa: E402
from mcsweep.scanning import find_transits  # noqa: E402
from mcsweep.scanning.ephemeris import gaia_position_au  # noqa: E402
from mcsweep.solver import AttitudeSpline, GlobalProblem, build_observations, solve_global  # noqa: E402
from mcsweep.solver.frame import rotation_matrices  # noqa: E402

START_JD = 2456863.9375  # 2014-07-25 10:30 TCB, start of routine operations (Prusti et al. 2016)


def make(n_stars: int, days: float, knot_days: float, seed: int = 5):
    rng = np.random.default_rng(seed)
    ra = rng.uniform(0.0, 360.0, n_stars)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n_stars)))
    tr = find_transits(ra, dec, START_JD, START_JD + days, compact=True)
    src = tr["source_index"].to_numpy().astype(np.int64)
    count = np.bincount(src, minlength=n_stars)
    keep = count >= 2
    new = np.cumsum(keep) - 1
    sel = keep[src]
    star, t, psi = new[src[sel]], tr["tcb_jd"].to_numpy()[sel], tr["scan_angle_deg"].to_numpy()[sel].astype(float)
    ra, dec = ra[keep], dec[keep]
    g = rng.uniform(12.0, 19.0, ra.size)
    noise = NoiseModel()
    spline = AttitudeSpline(START_JD, START_JD + days, knot_days)
    obs = build_observations(ra, dec, star, t, psi, gaia_position_au(t), t_ref_jd=START_JD + 0.5 * days,
                             sigma_al_mas=noise.sigma_al_mas(g)[star], sigma_ac_mas=noise.sigma_ac_mas(g)[star],
                             spline=spline)
    prior = prior_diagonal(1.0, 10.0)
    problem = GlobalProblem(obs, prior, ra, dec)
    x = np.column_stack([rng.normal(0, 1, ra.size), rng.normal(0, 1, ra.size), rng.uniform(0.1, 3, ra.size),
                         rng.normal(0, 5, ra.size), rng.normal(0, 5, ra.size)])
    a = rng.normal(0, 10.0, (obs.n_coef, 3))
    a[~problem.free] = 0.0
    h = problem.forward(problem.join(x, a)) + rng.standard_normal(obs.size)
    return problem, h, prior, ra, dec


def sparse_design(problem):
    obs = problem.obs
    n, m = obs.n_stars, obs.size
    rows = np.concatenate([np.repeat(np.arange(m), 5), np.repeat(np.arange(m), 12)])
    cols = np.concatenate([(5 * obs.star[:, None] + np.arange(5)).ravel(),
                           (5 * n + 3 * (obs.j0[:, None, None] + np.arange(4)[None, :, None])
                            + np.arange(3)[None, None, :]).ravel()])
    vals = np.concatenate([obs.src.ravel(), (obs.bval[:, :, None] * obs.att[:, None, :]).ravel()])
    A = sp.csr_matrix((vals, (rows, cols)), shape=(m, 5 * n + 3 * obs.n_coef))
    free = np.concatenate([np.ones(5 * n, bool), problem.free.ravel()])
    return A[:, free], free


def direct(problem, h, prior, ra, dec):
    A, free = sparse_design(problem)
    n = problem.obs.n_stars
    nf = int(free.sum())
    N = (A.T @ A).tocsc() + sp.diags(np.concatenate([np.tile(prior, n), np.zeros(nf - 5 * n)]))
    K = rotation_matrices(ra, dec)
    C = np.zeros((6, nf))
    for c in range(3):  # the six constraint rows (a loop over 3 axes only)
        C[c, 0:5 * n:5], C[c, 1:5 * n:5] = K[:, 0, c], K[:, 1, c]
        C[3 + c, 3:5 * n:5], C[3 + c, 4:5 * n:5] = K[:, 0, c], K[:, 1, c]
    W = sp.diags(np.r_[np.full(3, 1 / problem.w_pos), np.full(3, 1 / problem.w_pm)])
    kkt = sp.bmat([[N, sp.csr_matrix(C).T], [sp.csr_matrix(C), -W]]).tocsc()
    return spsolve(kkt, np.concatenate([A.T @ h, np.zeros(6)]))[:nf], free


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stars", type=int, default=20000)
    ap.add_argument("--days", type=float, default=10.0)
    ap.add_argument("--knot-days", type=float, default=0.5)
    args = ap.parse_args()
    print("machine shared with other jobs: CPU seconds (process_time); compare ratios only")
    problem, h, prior, ra, dec = make(args.stars, args.days, args.knot_days)
    print(f"system: {problem.obs.n_stars} stars, {problem.obs.size} measurements, {problem.size} unknowns")
    c0 = time.process_time()
    sol = solve_global(problem, h, rtol=1e-12, max_iter=5000)
    t_pcg = time.process_time() - c0
    it = len(sol.history)
    print(f"PCG: {t_pcg:.2f} s CPU, {it} iterations (converged {sol.converged}), {t_pcg / it * 1e3:.1f} ms/iteration")
    c0 = time.process_time()
    x_dir, free = direct(problem, h, prior, ra, dec)
    t_dir = time.process_time() - c0
    x_it = problem.join(sol.x, sol.attitude)[free]
    print(f"direct sparse (spsolve, KKT): {t_dir:.2f} s CPU; ratio direct/PCG = {t_dir / t_pcg:.2f}; "
          f"|x_PCG - x_direct| / |x_direct| = {np.linalg.norm(x_it - x_dir) / np.linalg.norm(x_dir):.2e}")
    A, _ = sparse_design(problem)
    c0 = time.process_time()
    # Without the prior and the frame penalty lsqr solves another (singular) system: the
    # prior rows are appended so the two are the same least-squares problem but the frame.
    n = problem.obs.n_stars
    P = sp.diags(np.sqrt(np.concatenate([np.tile(prior, n), np.zeros(A.shape[1] - 5 * n)])))
    out = lsqr(sp.vstack([A, P]).tocsr(), np.concatenate([h, np.zeros(A.shape[1])]), atol=1e-10, btol=1e-10,
               iter_lim=20000)
    t_lsqr = time.process_time() - c0
    print(f"lsqr (same design + prior rows): {t_lsqr:.2f} s CPU, {out[2]} iterations; ratio lsqr/PCG = "
          f"{t_lsqr / t_pcg:.2f}")
    for mult in (1, 2, 4):
        pb, hh, *_ = make(args.stars * mult, args.days, args.knot_days, seed=7)
        c0 = time.process_time()
        s = solve_global(pb, hh, rtol=1e-10, max_iter=5000)
        dt = time.process_time() - c0
        print(f"scaling: {pb.obs.n_stars:7d} stars {pb.obs.size:8d} measurements: {len(s.history)} iterations, "
              f"{dt / len(s.history) * 1e3:.1f} ms/iteration ({dt / len(s.history) / pb.obs.size * 1e9:.0f} "
              "ns per measurement and iteration)")
    print(f"peak memory (ru_maxrss): {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
