"""Benchmark of the global (primary) solver: convergence per prior, a direct sparse solve, lsqr, scaling.

Problem: random stars over the sky, the flown law's FoV transits over ``--days`` days with a
fraction ``--keep`` of the transits kept at random (so that, as in Table 3, many stars have
only 1-4 transits), AL + AC, noisy measurements, the prior of Eq. 18 (R = 10 /yr). In one run:

1. iterations to convergence per prior (0.01 mas, F90 ~ 1 mas, 10 F90 ~ 10 mas, 1000 mas) for
   the solver (:func:`mcsweep.solver.solve_global`: symmetric block Gauss-Seidel preconditioner
   with the banded Schur attitude block, precision-weighted frame constraint) and for the
   baseline it replaced, block-Jacobi PCG (``diag(B, N_aa)``, AGIS's S and A blocks side by
   side, Bombrun et al. 2012) on the same normal equations;
2. the direct solution of the same normal equations (:func:`mcsweep.solver.direct.solve_direct`: ``splu`` of the
   equilibrated bordered system plus two refinement steps): CPU ratio and agreement;
3. ``scipy.sparse.linalg.lsqr`` on the same weighted design plus prior rows: CPU ratio;
4. executor overhead: the same solve in-process and with every pass in 2 forked workers that
   keep their blocks (``workers=2``; a map-like executor that re-sends the blocks every pass is
   no longer offered: it cost more than the work, :func:`mcsweep.solver.solve_global`);
5. scaling with the number of stars (3 sizes, then the largest with every transit kept, the
   experiment's density of measurements per star): ms per iteration (the iterations alone,
   and with the one-off setup and final passes), ns per measurement and iteration, bytes per
   measurement held by the solver, peak traced memory, and the memory-bandwidth floor
   measured in the same run (two plain numpy streaming reads of the solver's stored bytes
   per iteration) with the ratio of the solver's time to it;
6. an extrapolation to the issue's full scale;
7. AGIS's knot density (30 s knots): the two compiled passes over one solver block of
   32768 stars out of a 1.5e6-star sky, the block's stars taken in random order (every block a
   sample of the whole sky) and in sky order (HEALPix level-12 nested, the primary experiment's
   order: :func:`mcsweep.experiments.global_solution.classes.sky_order`): ns per measurement of each.

Times are CPU seconds of this process (``time.process_time``) except where marked wall: the
machine is shared, so only ratios measured in this run mean anything.

Run: ``python benchmarks/bench_primary.py [--stars 2000] [--days 365] [--knot-days 4] [--keep 0.25]
[--workers-stars 40000] [--sky-stars 1500000] [--only-sky-order]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402
import tracemalloc  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from scipy.linalg import cho_solve_banded, cholesky_banded  # noqa: E402
from scipy.sparse.linalg import lsqr  # noqa: E402

from mcsweep.astrometry.noise import NoiseModel  # noqa: E402
from mcsweep.experiments.global_solution.classes import sky_order  # noqa: E402
from mcsweep.astrometry.solve import prior_diagonal  # noqa: E402
from mcsweep.scanning import find_transits  # noqa: E402
from mcsweep.scanning.ephemeris import gaia_position_au  # noqa: E402
from mcsweep.solver import AttitudeSpline, GlobalProblem, build_measurements, solve_global  # noqa: E402
from mcsweep.solver import kernels  # noqa: E402
from mcsweep.solver.attitude_update import attitude_band, free_coefficients  # noqa: E402
from mcsweep.solver.problem import SOLVER_BLOCK_STARS, make_blocks  # noqa: E402
from mcsweep.solver.direct import normal_norm, solve_direct  # noqa: E402

START_JD = 2456863.9375  # 2014-07-25 10:30 TCB, start of routine operations (Prusti et al. 2016)
PRIORS_MAS = {"0.01 mas": 0.01, "F90 (1 mas)": 1.0, "10 F90 (10 mas)": 10.0, "1000 mas": 1000.0}
#: Full scale of the paper's primary solution (Sect. 4.2, Table 3): the paper's three classes
#: of 5e5 stars (Sect. 4), one year, 20 % dead time (conf/experiment/primary.yaml's 3 h knots;
#: measured: docs/notes/table3/reproduction.md).
FULL_STARS, FULL_DAYS, FULL_LIVE = 1.5e6, 365.25, 0.8


def make_obs(n_stars: int, days: float, knot_days: float, keep: float, seed: int = 5):
    rng = np.random.default_rng(seed)
    ra = rng.uniform(0.0, 360.0, n_stars)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n_stars)))
    tr = find_transits(ra, dec, START_JD, START_JD + days, compact=True)
    tr = tr[rng.uniform(size=len(tr)) < keep]
    src = tr["source_index"].to_numpy().astype(np.int64)
    keep_star = np.bincount(src, minlength=n_stars) >= 1
    new = np.cumsum(keep_star) - 1
    star, t, psi = new[src], tr["tcb_jd"].to_numpy(), tr["scan_angle_deg"].to_numpy().astype(float)
    ra, dec = ra[keep_star], dec[keep_star]
    g = rng.uniform(12.0, 19.0, ra.size)
    noise = NoiseModel()
    spline = AttitudeSpline(START_JD, START_JD + days, knot_days)
    obs = build_measurements(ra, dec, star, t, psi, gaia_position_au(t), t_ref_jd=START_JD + 0.5 * days,
                             sigma_al_mas=noise.sigma_al_mas(g)[star], sigma_ac_mas=noise.sigma_ac_mas(g)[star],
                             spline=spline)
    x = np.column_stack([rng.normal(0, 1, ra.size), rng.normal(0, 1, ra.size), rng.uniform(0.1, 3, ra.size),
                         rng.normal(0, 5, ra.size), rng.normal(0, 5, ra.size)])
    a = rng.normal(0, 10.0, (obs.n_coef, 3))
    return obs, ra, dec, x, a, rng


def data_for(problem, x, a, rng):
    a = np.where(problem.free, a, 0.0)
    return problem.forward(problem.join(x, a)) + rng.standard_normal(problem.n_measurements)


class BandedAttitudeSolver:
    """Cholesky factor of the attitude block, reused for every solve (the baseline's
    preconditioner; the solver no longer uses it).

    Parameters
    ----------
    ab : ndarray
        Upper band storage of the attitude normal matrix (:func:`attitude_band`).
    """

    def __init__(self, ab):
        ab = np.array(ab, dtype=float)
        self.free = free_coefficients(ab)
        fixed = ~self.free.ravel()
        ab[-1, fixed] = 1.0  # rows/columns of unobserved coefficients are already zero
        self.cholesky = cholesky_banded(ab, lower=False)

    def solve(self, rhs) -> np.ndarray:
        """``N_aa^-1 rhs`` for ``rhs (n_coef, 3)``; unobserved coefficients stay zero."""
        rhs = np.where(self.free, rhs, 0.0)
        return cho_solve_banded((self.cholesky, False), rhs.ravel()).reshape(-1, 3)


def wall(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` and its wall time [s]."""
    w0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - w0


def streaming_seconds(nbytes: int, repeats: int = 5) -> float:
    """CPU seconds of one plain streaming read of ``nbytes`` (numpy sum over a float64 array),
    best of ``repeats``: the memory-bandwidth floor of a pass over the solver's stored bytes."""
    a = np.ones(max(nbytes // 8, 1))
    best = np.inf
    for _ in range(repeats):
        c0 = time.process_time()
        a.sum()
        best = min(best, time.process_time() - c0)
    return best


def block_jacobi(problem, obs, h, rtol=1e-8, update_tol_uas=1e-2, max_iter=5000):
    """The baseline: PCG with diag(B, N_aa) (the solver before this version), same stopping rule."""
    att = BandedAttitudeSolver(attitude_band(obs))
    pb, free = problem, problem.free

    def prec(r):
        rs, ra = pb.split(r)
        return pb.join(np.einsum("nij,nj->ni", pb.src_inv, rs), np.where(free, att.solve(ra), 0.0))

    b_s, b_a = problem.split(problem.apply(np.zeros(problem.size)))  # zeros: just shapes
    star, src, att_p, j0, bval = problem.design()
    b_s = np.stack([np.bincount(star, src[:, i] * h, minlength=pb.n_stars) for i in range(5)], axis=1)
    b_a = np.zeros((pb.n_coef, 3))
    for k in range(4):
        for c in range(3):
            b_a[:, c] += np.bincount(j0 + k, bval[:, k] * att_p[:, c] * h, minlength=pb.n_coef)
    b_a[~free] = 0.0
    b = pb.join(b_s, b_a)
    x = np.zeros_like(b)
    r = b.copy()
    z = prec(r)
    p = z.copy()
    rz = r @ z
    for it in range(1, max_iter + 1):
        q = pb.apply(p)
        alpha = rz / (p @ q)
        x += alpha * p
        r -= alpha * q
        if (1e3 * np.max(np.abs(alpha * p)) < update_tol_uas and np.linalg.norm(r) / np.linalg.norm(b) < rtol
                and it >= 2):
            return x, it
        z = prec(r)
        rz, rz_old = r @ z, rz
        p = z + (rz / rz_old) * p
    return x, max_iter


def block_in_order(ra, dec, take, days: float, knot_seconds: float, seed: int):
    """The solver block of the stars ``take`` (indices into ``ra, dec``) with a ``knot_seconds``
    spline over ``days`` (no gaps), every transit kept, AL + AC, unit star blocks."""
    rng = np.random.default_rng(seed)
    ra, dec = ra[take], dec[take]
    tr = find_transits(ra, dec, START_JD, START_JD + days, compact=True)
    star, t = tr["source_index"].to_numpy().astype(np.int64), tr["tcb_jd"].to_numpy()
    g = rng.uniform(11.0, 19.5, ra.size)
    noise = NoiseModel()
    spline = AttitudeSpline(START_JD, START_JD + days, knot_seconds / 86400.0)
    obs = build_measurements(ra, dec, star, t, tr["scan_angle_deg"].to_numpy().astype(float), gaia_position_au(t),
                             t_ref_jd=START_JD + 0.5 * days, sigma_al_mas=noise.sigma_al_mas(g)[star],
                             sigma_ac_mas=noise.sigma_ac_mas(g)[star], spline=spline)
    (blk,) = make_blocks(obs, ra, dec, block_stars=ra.size)
    return blk


def pass_ns(blk, rng, repeats: int = 3) -> tuple[float, float]:
    """CPU ns per measurement of the forward and the back pass over ``blk`` (best of ``repeats``)."""
    blk = dataclasses.replace(blk, binv=np.tile(np.eye(5), (blk.n, 1, 1)))
    z_a = rng.standard_normal((blk.n_coef, 3))
    fwd = back = np.inf
    for _ in range(repeats):
        y, out = rng.standard_normal((blk.n, 5)), np.zeros((blk.n_coef, 3))
        c0 = time.process_time()
        kernels.precondition_forward(blk, y, out)
        fwd = min(fwd, time.process_time() - c0)
        ya = np.zeros((blk.n_coef, 3))
        c0 = time.process_time()
        kernels.precondition_back(blk, y, z_a, ya)
        back = min(back, time.process_time() - c0)
    m = blk.t.size
    return 1e9 * fwd / m, 1e9 * back / m


def sky_order_section(n_sky: int, days: float):
    print(f"\n7. AGIS's knot density (30 s knots): one block of {SOLVER_BLOCK_STARS} stars of a {n_sky:.2g}-star "
          f"sky over {days:g} days, its stars in random order and in sky order")
    rng = np.random.default_rng(17)
    ra = rng.uniform(0.0, 360.0, n_sky)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n_sky)))
    mid = (n_sky // SOLVER_BLOCK_STARS // 2) * SOLVER_BLOCK_STARS  # a block from the middle of the order
    res = {}
    for name, order in (("random order", rng.permutation(n_sky)), ("sky order", sky_order(ra, dec))):
        blk = block_in_order(ra, dec, order[mid:mid + SOLVER_BLOCK_STARS], days, 30.0, seed=3)
        fwd, back = pass_ns(blk, rng)
        res[name] = fwd + back
        print(f"  {name:12s}: {blk.t.size} measurements, {blk.seg.size} runs of equal first coefficient "
              f"({blk.t.size / blk.seg.size:.1f} measurements per run): forward {fwd:.1f} ns, back {back:.1f} ns per "
              "measurement")
    print(f"  sky order / random order: {res['sky order'] / res['random order']:.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stars", type=int, default=2000)
    ap.add_argument("--days", type=float, default=365.0)
    ap.add_argument("--knot-days", type=float, default=4.0)
    ap.add_argument("--keep", type=float, default=0.25)
    ap.add_argument("--workers-stars", type=int, default=40000, help="stars of the forked-worker comparison")
    ap.add_argument("--sky-stars", type=int, default=1500000, help="stars of the sky of section 7")
    ap.add_argument("--only-sky-order", action="store_true", help="run section 7 only")
    args = ap.parse_args()
    if args.only_sky_order:
        sky_order_section(args.sky_stars, args.days)
        return
    print("machine shared with other jobs: CPU seconds (process_time); compare ratios only")
    obs, ra, dec, x, a, rng = make_obs(args.stars, args.days, args.knot_days, args.keep)
    n_fov = np.bincount(obs.star[~obs.is_ac], minlength=obs.n_stars)
    print(f"system: {obs.n_stars} stars ({(n_fov <= 4).mean():.0%} with <= 4 transits), {obs.size} measurements, "
          f"{5 * obs.n_stars + 3 * obs.n_coef} unknowns")

    print("\n1-3. per prior: iterations (rtol 1e-8, largest update < 0.01 uas), agreement with the direct solve")
    kw = dict(rtol=1e-8, update_tol_uas=1e-2, max_iter=5000)
    iters = {}
    for label, sig in PRIORS_MAS.items():
        problem = GlobalProblem(obs, prior_diagonal(sig, 10.0), ra, dec)
        h = data_for(problem, x, a, rng)
        c0 = time.process_time()
        sol = solve_global(problem, h, **kw)
        t_pcg = time.process_time() - c0
        c0 = time.process_time()
        x_bj, it_bj = block_jacobi(problem, obs, h, **kw)
        t_bj = time.process_time() - c0
        c0 = time.process_time()
        x_dir, free, A = solve_direct(problem, h)
        t_dir = time.process_time() - c0
        x_it = problem.join(sol.x, sol.attitude)[free]
        rel = np.linalg.norm(x_it - x_dir) / np.linalg.norm(x_dir)
        # the error in the norm the solver's energy criterion bounds (|dx|_N / |x|_N)
        rel_n = normal_norm(problem, x_it - x_dir) / normal_norm(problem, x_dir)
        rel_bj = np.linalg.norm(x_bj[free] - x_dir) / np.linalg.norm(x_dir)
        iters[label] = len(sol.history)
        print(f"  {label:16s}: PCG {len(sol.history):4d} it {t_pcg:6.2f} s, |dx|/|x| vs direct {rel:.1e} "
              f"(in the normal equations' norm {rel_n:.1e}) | "
              f"block Jacobi {it_bj:4d} it {t_bj:6.2f} s, {rel_bj:.1e} | direct {t_dir:.2f} s "
              f"(direct/PCG {t_dir / t_pcg:.2f})")
        if label.startswith("F90"):
            n = obs.n_stars
            P = sp.diags(np.sqrt(np.concatenate([problem.prior.ravel(), np.zeros(A.shape[1] - 5 * n)])))
            c0 = time.process_time()
            out = lsqr(sp.vstack([A, P]).tocsr(), np.concatenate([h, np.zeros(A.shape[1])]), atol=1e-10,
                       btol=1e-10, iter_lim=20000)
            t_lsqr = time.process_time() - c0
            print(f"  lsqr (same design + prior rows, no frame rows), F90: {t_lsqr:.2f} s, {out[2]} iterations; "
                  f"lsqr/PCG = {t_lsqr / t_pcg:.2f}")

    print("\n4. executor overhead (F90, wall seconds): in-process vs 2 forked workers that keep their blocks")
    # the forked workers pay per pass, not per measurement: a larger problem (all transits kept)
    o, r_, d_, xx, aa, rr = make_obs(args.workers_stars, args.days, args.knot_days, 1.0, seed=11)
    big = GlobalProblem(o, prior_diagonal(1.0, 10.0), r_, d_, block_stars=max(1, o.n_stars // 8))
    hb = data_for(big, xx, aa, rr)
    s1, w_one = wall(solve_global, big, hb, **kw)
    s2, w_two = wall(solve_global, big, hb, workers=2, **kw)
    same = np.array_equal(s1.x, s2.x) and np.array_equal(s1.attitude, s2.attitude)
    print(f"  forked workers that keep their blocks (solver.resident), {o.n_stars} stars, {o.size} measurements, "
          f"{len(big.blocks)} blocks: in-process {w_one:.2f} s, 2 workers {w_two:.2f} s, speed-up "
          f"{w_one / w_two:.2f} (2 cores, both needed idle); bit-identical: {same}")

    print("\n5. scaling (F90 prior), sizes x1, x2, x4 stars; then x4 with every transit kept (the experiment's "
          "~28 measurements per star instead of ~9)")
    rows = []
    for mult, keep in ((1, args.keep), (2, args.keep), (4, args.keep), (4, 1.0)):
        o, r_, d_, xx, aa, rr = make_obs(args.stars * mult, args.days, args.knot_days, keep, seed=7)
        tracemalloc.start()
        pb = GlobalProblem(o, prior_diagonal(1.0, 10.0), r_, d_)
        hh = data_for(pb, xx, aa, rr)
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        c0 = time.process_time()
        s = solve_global(pb, hh, **kw)
        dt = time.process_time() - c0
        peak = tracemalloc.get_traced_memory()[1] - base
        tracemalloc.stop()
        # the iterations alone (the records' wall clock), and everything (CPU, with the setup
        # and final passes, which weigh more the fewer the iterations)
        it_only = s.history[-1].seconds / len(s.history)
        per_it = dt / len(s.history)
        floor = streaming_seconds(int(pb.nbytes_per_measurement * o.size))
        rows.append((o.size, it_only, pb.nbytes_per_measurement))
        print(f"  {o.n_stars:7d} stars {o.size:8d} measurements ({o.size / o.n_stars:.0f} per star): "
              f"{len(s.history)} it, {it_only * 1e3:.1f} ms/it in the iterations = "
              f"{it_only / o.size * 1e9:.0f} ns/(measurement iteration); with setup and final pass "
              f"{per_it / o.size * 1e9:.0f} ns; solver storage {pb.nbytes_per_measurement:.0f} B/measurement, "
              f"solve peak above storage {peak / 2**20:.0f} MB ({peak / o.size:.0f} B/measurement)")
        print(f"      memory-bandwidth floor (2 streaming reads of the stored bytes per iteration, plain numpy, "
              f"this run): {2 * floor / o.size * 1e9:.1f} ns/(measurement iteration); ratio "
              f"{it_only / (2 * floor):.1f} (goal: <= 40 ns/(measurement iteration), docs/notes/table3/solver_cost.md)")

    print("\n6. extrapolation to full scale (1.5e6 stars, 1 year, 20 % dead time; measured: docs/notes/table3/solver_cost.md)")
    m_per_star_day = rows[-2][0] / (args.stars * 4 * args.days * args.keep)
    m_full = m_per_star_day * FULL_STARS * FULL_DAYS * FULL_LIVE
    ns = rows[-1][1] / rows[-1][0]  # the row at the experiment's density of measurements per star
    it_total = sum(iters[k] for k in ("F90 (1 mas)", "10 F90 (10 mas)", "1000 mas"))
    store = rows[-1][2]  # measured: per-measurement storage plus the per-star blocks at this size
    print(f"  ~{m_full:.2e} measurements ({m_per_star_day:.3f} per star and day), {ns * 1e9:.0f} ns/(measurement "
          f"iteration) -> {ns * m_full:.0f} s per iteration on one core (workers=2 divides the passes' share, "
          f"section 4); iterations for the 3 priors here: {it_total} -> {ns * m_full * it_total / 60:.0f} min")
    print(f"  memory: solver {store:.0f} B/measurement -> {store * m_full / 2**30:.1f} GB (compact=True: "
          f"{(store - 16) * m_full / 2**30:.1f} GB), plus the experiment's measurements (8 B/measurement, "
          f"{8 * m_full / 2**30:.1f} GB; it builds the blocks block by block, without a whole Measurements)")
    print("  (iteration counts may grow with the problem's size and knot density)")
    sky_order_section(args.sky_stars, args.days)

if __name__ == "__main__":
    main()
