"""Throughput of the batched astrometric solutions (normal equations and prior, Eqs. 9-13,
18), against performance targets.

Solves ``--n-stars`` stars (default 1e6), each with its own geometry (random direction,
``--k`` FoV transits at random epochs in Oct 2014 - Dec 2015 with random scan angles,
random G), with the paper's prior sigma_F90(l, b, G) and R = 10/yr, in chunks of
``--chunk`` stars so that memory stays flat. Reports, per stage, the time and the
throughput in star-solutions per second:

* design     Eq. 1 design matrix (AL + AC rows unless --al-only), noise model
* simulate   h = A x_true + N(0, 1)
* normal     N0 = A'A, b0 = A'h
* solve      x = (N0 + Np)^-1 b0 and C = (N0 + Np)^-1 (Eqs. 11-13, 18)

"core" = normal + solve (normal-equation formation from A plus the solution with its
covariance); "full" = all four. Generating the random geometry (including the
observer ephemeris) is set-up and not counted.

Two references are measured in the same run on a subsample of the first chunk and
scaled per star: a naive Python loop over stars (``A.T @ A``, ``numpy.linalg.solve``
and ``numpy.linalg.inv`` per star; same scope as "core"), and numpy's stacked
``linalg.solve``/``linalg.inv`` on the (n, 5, 5) arrays. The batched results are
checked against the loop. Peak memory is ``resource.getrusage(...).ru_maxrss``.

Run on one core: the script pins BLAS/OpenMP to one thread before importing numpy.

    python benchmarks/bench_solve.py                 # 1e6 stars
    python benchmarks/bench_solve.py --n-stars 200000
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from mcsweep.astrometry.design import design_matrix, reference_epoch, years_since  # noqa: E402
from mcsweep.astrometry.measurements import simulate  # noqa: E402
from mcsweep.astrometry.noise import NoiseModel  # noqa: E402
from mcsweep.astrometry.solve import DEFAULT_RATIO_R, normal_equations, prior_diagonal, solve_with_prior  # noqa: E402
from mcsweep.prior import sigma_f90  # noqa: E402
from mcsweep.scanning.ephemeris import gaia_position_au  # noqa: E402

STAGES = ("design", "simulate", "normal", "solve")
#: Transit epochs: Oct 2014 - end 2015 (paper Sect. 3.1), TCB Julian dates.
START_JD, END_JD = 2456931.5, 2457388.5
#: Required speed-up over the naive per-star loop and throughput per core (stars/s).
TARGET_SPEEDUP = 30.0
TARGET_RATE = 2e6


def make_geometry(rng, n, k):
    """Random stars with their own transits; returns the inputs of design_matrix."""
    ra = rng.uniform(0.0, 360.0, n)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    l_deg = rng.uniform(0.0, 360.0, n)  # direction for the prior only (synthetic stars)
    b_deg = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    g = rng.uniform(6.0, 20.0, n)
    jd = np.sort(rng.uniform(START_JD, END_JD, (n, k)), axis=1)
    psi = rng.uniform(0.0, 360.0, (n, k))
    obs = gaia_position_au(jd)
    t_yr = years_since(jd, reference_epoch(jd))
    plx = rng.exponential(1.0, n)
    x_true = np.column_stack([np.zeros((n, 2)), plx, rng.normal(0.0, 10.0 * plx[:, None], (n, 2))])
    return dict(ra=ra, dec=dec, l_deg=l_deg, b_deg=b_deg, g=g, t_yr=t_yr, psi=psi, obs=obs, x_true=x_true)


def run_chunk(geo, rng, noise, timings):
    sigma_p = sigma_f90(geo["l_deg"], geo["b_deg"], geo["g"])  # the prior is an input here
    t0 = time.perf_counter()
    sig_al, sig_ac = noise.design_sigmas(geo["g"])
    A = design_matrix(geo["ra"], geo["dec"], geo["t_yr"], geo["psi"], geo["obs"],
                      sigma_al_mas=sig_al, sigma_ac_mas=sig_ac)
    t1 = time.perf_counter()
    h = simulate(A, geo["x_true"], rng)
    t2 = time.perf_counter()
    N0, b0 = normal_equations(A, h)
    t3 = time.perf_counter()
    sol = solve_with_prior(N0, b0, sigma_p, DEFAULT_RATIO_R)
    t4 = time.perf_counter()
    for name, dt in zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
        timings[name] += dt
    return A, h, sigma_p, sol


def naive_loop(A, h, sigma_p):
    """Per-star Python loop with numpy.linalg (the reference implementation)."""
    diag = prior_diagonal(sigma_p, DEFAULT_RATIO_R)
    n = A.shape[0]
    x = np.empty((n, 5))
    cov = np.empty((n, 5, 5))
    t0 = time.perf_counter()
    for i in range(n):
        a = A[i]
        N = a.T @ a + np.diag(diag[i])
        b = a.T @ h[i]
        x[i] = np.linalg.solve(N, b)
        cov[i] = np.linalg.inv(N)
    return time.perf_counter() - t0, x, cov


def stacked_numpy(A, h, sigma_p):
    """numpy's own stacked solve/inv on (n, 5, 5) (LAPACK called per matrix in C)."""
    diag = prior_diagonal(sigma_p, DEFAULT_RATIO_R)
    t0 = time.perf_counter()
    At = np.swapaxes(A, 1, 2)
    N = At @ A + np.einsum("ni,ij->nij", diag, np.eye(5))
    b = (At @ h[..., None])[..., 0]
    x = np.linalg.solve(N, b[..., None])[..., 0]
    cov = np.linalg.inv(N)
    return time.perf_counter() - t0, x, cov


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-stars", type=float, default=1e6, help="number of stars (default 1e6)")
    ap.add_argument("--k", type=int, default=10, help="FoV transits per star (default 10)")
    ap.add_argument("--chunk", type=int, default=16384, help="stars per chunk (default 16384)")
    ap.add_argument("--loop-sample", type=int, default=5000, help="stars timed in the naive loop")
    ap.add_argument("--al-only", action="store_true", help="AL rows only (default: AL and AC)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    n = int(args.n_stars)
    if n < 1 or args.k < 1 or args.chunk < 1 or args.loop_sample < 1:
        ap.error("--n-stars, --k, --chunk and --loop-sample must be positive")

    noise = NoiseModel(use_ac=not args.al_only)
    rows = args.k * (1 if args.al_only else 2)
    print(f"bench_solve: {n} stars x {args.k} FoV transits ({rows} rows: "
          f"{'AL' if args.al_only else 'AL+AC'}), prior sigma_F90(l, b, G), R = {DEFAULT_RATIO_R}/yr, "
          f"chunks of {args.chunk}; numpy {np.__version__}; "
          f"BLAS threads {os.environ.get('OPENBLAS_NUM_THREADS')}")

    seeds = np.random.SeedSequence(args.seed)
    geo_rng, noise_rng = (np.random.default_rng(s) for s in seeds.spawn(2))
    timings = dict.fromkeys(STAGES, 0.0)
    t_setup = 0.0
    cpu0 = time.process_time()
    sample = None
    done = 0
    while done < n:
        m = min(args.chunk, n - done)
        t0 = time.perf_counter()
        geo = make_geometry(geo_rng, m, args.k)
        t_setup += time.perf_counter() - t0
        A, h, sigma_p, sol = run_chunk(geo, noise_rng, noise, timings)
        if sample is None:
            s = min(args.loop_sample, m)
            sample = (np.array(A[:s]), np.array(h[:s]), sigma_p[:s], sol.x[:s].copy(), sol.cov[:s].copy())
        done += m
        del A, h, sol, geo
    cpu = time.process_time() - cpu0
    wall = sum(timings.values())

    A_s, h_s, sp_s, x_s, cov_s = sample
    s = len(sp_s)
    t_loop, x_loop, cov_loop = naive_loop(A_s, h_s, sp_s)
    t_stack, x_stack, cov_stack = stacked_numpy(A_s, h_s, sp_s)
    err_x = np.max(np.abs(x_s - x_loop) / np.sqrt(np.einsum("nii->ni", cov_loop)))
    err_c = np.max(np.abs(cov_s - cov_loop)) / np.max(np.abs(cov_loop))

    core = timings["normal"] + timings["solve"]
    print("\nstage        time [s]   star-solutions/s")
    for name in STAGES:
        print(f"{name:10s} {timings[name]:10.3f}   {n / timings[name]:12.3e}")
    print(f"{'core':10s} {core:10.3f}   {n / core:12.3e}   (normal + solve)")
    print(f"{'full':10s} {wall:10.3f}   {n / wall:12.3e}   (design + simulate + normal + solve)")
    print(f"(set-up, not counted: random geometry and ephemeris {t_setup:.3f} s; "
          f"CPU/wall over the run {cpu / (wall + t_setup):.2f})")
    loop_rate = s / t_loop
    print(f"\nnaive Python loop (numpy.linalg per star, {s} stars): {loop_rate:.3e} star-solutions/s")
    print(f"numpy stacked linalg.solve + inv ({s} stars):          {s / t_stack:.3e} star-solutions/s")
    print(f"speed-up of core over the naive loop: {(n / core) / loop_rate:.1f}x "
          f"(target >= {TARGET_SPEEDUP:.0f}x); full pipeline: {(n / wall) / loop_rate:.1f}x")
    print(f"core throughput {n / core:.3e}/s (target >= {TARGET_RATE:.0e}/s)")
    print(f"agreement with the loop: max |dx|/sigma = {err_x:.1e}, max |dC|/max|C| = {err_c:.1e}")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux
    print(f"peak memory (ru_maxrss): {peak_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
