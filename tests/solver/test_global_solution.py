"""The global solver against independent references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import BSpline

from mcsweep.astrometry.design import design_matrix
from mcsweep.astrometry.solve import normal_equations, prior_diagonal, solve_with_prior
from mcsweep.solver import (GlobalProblem, attitude_band, band_to_dense, fit_frame, frame_attitude,
                            frame_offsets, solve_global)
from mcsweep.solver.direct import solve_direct, sparse_design
from mcsweep.solver.blocks import schur_bandwidth
from mcsweep.solver.problem import SOLVER_BLOCK_STARS
from mcsweep.solver.source_update import solve_sources, source_normals
from mcsweep.scanning.ephemeris import gaia_position_au
from mcsweep.prior import sigma_f90

#: Band storage and dense products of the same sums (different summation order).
RTOL_SUMS = 1e-12
#: Iterative (PCG, rtol 1e-10) versus direct sparse solution, |dx| / |x|.
RTOL_ITER_DIRECT = 1e-6
#: PCG iterations allowed on the test problems (measured: <= 100 for every prior).
MAX_ITERATIONS = 200
#: Source update with the attitude fixed versus astrometry.solve (same sums, other code).
RTOL_SECONDARY = 1e-9
#: Recovery of noiseless truth after the frame correction [microarcsec].
RECOVERY_UAS = 1.0



def _source_rhs(obs, r):
    """``A_s' r`` per star (n, 5), the sums written out (a reference, not the solver's path)."""
    return np.stack([np.bincount(obs.star, obs.src[:, i] * r, minlength=obs.n_stars) for i in range(5)], axis=1)


def _attitude_rhs(obs, r):
    """``A_a' r`` (n_coef, 3): each measurement's four cubic-spline basis values times its
    attitude partials, summed per coefficient (a reference, checked against the dense design)."""
    out = np.zeros((obs.n_coef, 3))
    for k in range(4):
        for c in range(3):
            out[:, c] += np.bincount(obs.j0 + k, obs.bval[:, k] * r * obs.att[:, c], minlength=obs.n_coef)
    return out

def _sparse_design(P, problem=None):
    """The full design matrix built element by element from the partials (independent of the solver):
    those of the observations, or the ones a problem stores (float32 when compact)."""
    obs = P["obs"]
    parts = (obs.star, obs.src, obs.att, obs.j0, obs.bval) if problem is None else problem.design()
    return sparse_design(*parts, obs.n_stars, obs.n_coef)


def _truth(P, rng, zero_motion=True):
    n, obs = P["obs"].n_stars, P["obs"]
    x = np.column_stack([rng.normal(0, 5, n), rng.normal(0, 5, n), rng.uniform(0.2, 3.0, n),
                         rng.normal(0, 5, n), rng.normal(0, 5, n)])
    if zero_motion:  # a prior centred on the truth cannot bias the solution
        x[:, 2:] = 0.0
    a = rng.normal(0, 10.0, (obs.n_coef, 3))
    return x, a


def test_spline_basis_matches_scipy_bspline(small_problem):
    spline, t = small_problem["spline"], small_problem["obs"].tcb_jd
    coef = np.random.default_rng(1).normal(size=(spline.n_coef, 3))
    ref = BSpline(spline.knots, coef, 3)(t)
    np.testing.assert_allclose(spline.evaluate(coef, t), ref, rtol=0, atol=1e-12)
    lin = spline.evaluate(spline.greville()[:, None], t)[:, 0]  # f(t) = t is in the space
    np.testing.assert_allclose(lin, t, rtol=1e-14)


def test_banded_attitude_normal_matrix_equals_dense(small_problem):
    obs = small_problem["obs"]
    A = _sparse_design(small_problem)[:, 5 * obs.n_stars:]
    dense = (A.T @ A).toarray()
    band = band_to_dense(attitude_band(obs))
    np.testing.assert_allclose(band, dense, rtol=RTOL_SUMS, atol=RTOL_SUMS * np.abs(dense).max())
    r = np.random.default_rng(2).normal(size=obs.size)
    np.testing.assert_allclose(_attitude_rhs(obs, r).ravel(), A.T @ r, rtol=RTOL_SUMS,
                               atol=RTOL_SUMS * np.abs(A.T @ r).max())


def test_noiseless_recovery_of_attitude_in_spline_space(small_problem):
    P = small_problem
    obs, rng = P["obs"], np.random.default_rng(11)
    x_true, a_true = _truth(P, rng)
    problem = GlobalProblem(obs, prior_diagonal(10.0, 10.0), P["ra"], P["dec"])
    a_true[~problem.free] = 0.0  # unobserved coefficients are held at zero by construction
    h = problem.forward(problem.join(x_true, a_true))
    sol = solve_global(problem, h, rtol=1e-12, max_iter=3000)
    assert sol.converged
    dx = sol.x - x_true
    eps, omega = fit_frame(dx, P["ra"], P["dec"])
    dx -= frame_offsets(P["ra"], P["dec"], eps, omega)
    t = obs.tcb_jd
    att_err = P["spline"].evaluate(sol.attitude - a_true, t) - frame_attitude(eps, omega, t, P["t_ref"])
    assert 1e3 * np.sqrt(np.mean(att_err ** 2)) < RECOVERY_UAS
    assert 1e3 * np.sqrt(np.mean(dx[:, :2] ** 2)) < RECOVERY_UAS
    assert 1e3 * np.abs(dx).max() < 10 * RECOVERY_UAS


def _agreement(P, prior, seed, max_iter=2000, compact=False):
    obs, rng = P["obs"], np.random.default_rng(seed)
    x_true, a_true = _truth(P, rng, zero_motion=False)
    problem = GlobalProblem(obs, prior, P["ra"], P["dec"], compact=compact)
    a_true[~problem.free] = 0.0
    h = problem.forward(problem.join(x_true, a_true)) + rng.normal(size=obs.size)
    sol = solve_global(problem, h, rtol=1e-10, update_tol_uas=1e-3, max_iter=max_iter)
    # The same normal equations solved directly (sparse LU of the bordered system).
    direct, free, _ = solve_direct(problem, h)
    iterative = problem.join(sol.x, sol.attitude)[free]
    return sol, np.linalg.norm(iterative - direct) / np.linalg.norm(direct)


def test_iterative_equals_direct_sparse_solution(small_problem):
    sol, rel = _agreement(small_problem, prior_diagonal(2.0, 10.0), 12)
    print(f"2 mas prior: {len(sol.history)} PCG iterations, |x_PCG - x_direct| / |x_direct| = {rel:.1e}")
    assert sol.converged and rel < RTOL_ITER_DIRECT


@pytest.mark.parametrize("prior", ["0.01mas", "1mas", "1000mas", "F90", "10F90"])
def test_iterative_equals_direct_for_every_prior(weak_problem, prior):
    # Table 3's priors and the extremes of Table 2. Before the block Gauss-Seidel
    # preconditioner and the precision-weighted frame constraint, PCG stopped mas away
    # from this solution at 1000 mas (thousands of iterations to get close).
    P = weak_problem
    if prior.endswith("F90"):
        sig = float(prior[:-3] or 1) * sigma_f90(P["ra"], P["dec"], P["g"])
    else:
        sig = float(prior[:-3])
    sol, rel = _agreement(P, prior_diagonal(sig, 10.0), 21)
    print(f"prior {prior}: {len(sol.history)} PCG iterations, |x_PCG - x_direct| / |x_direct| = {rel:.1e}")
    n_fov = np.bincount(P["star"])
    assert (n_fov <= 2).sum() > 100 and (n_fov > 4).sum() > 100  # both of Table 3's subsets
    assert sol.converged and rel < RTOL_ITER_DIRECT
    assert len(sol.history) < MAX_ITERATIONS


def test_attitude_fixed_to_truth_reproduces_secondary_solution(small_problem):
    P = small_problem
    obs, rng = P["obs"], np.random.default_rng(13)
    x_true, a_true = _truth(P, rng, zero_motion=False)
    # float64 partials: the secondary solution below is built from them (compact storage
    # would change the measurement model by its float32 rounding, 6e-8 relative)
    problem = GlobalProblem(obs, prior_diagonal(1.0, 10.0), P["ra"], P["dec"], compact=False)
    noise = rng.normal(size=obs.size)
    h = problem.forward(problem.join(x_true, a_true)) + noise
    _, a_part = problem.split(problem.join(np.zeros_like(x_true), a_true))
    h_att = h - problem.forward(problem.join(np.zeros_like(x_true), a_part))
    x, cov, ok = solve_sources(source_normals(obs), _source_rhs(obs, h_att), prior_diagonal(1.0, 10.0))
    # Secondary solution: padded per-star design of astrometry.design, the same noise.
    n = obs.n_stars
    al = ~obs.is_ac
    order = np.argsort(obs.star[al], kind="stable")
    star_al = obs.star[al][order]
    count = np.bincount(star_al, minlength=n)
    k = count.max()
    col = np.arange(star_al.size) - np.concatenate([[0], np.cumsum(count)])[star_al]
    tr, s = P["transits"], P["star"]
    assert np.array_equal(s, obs.star[al])
    t, psi = tr["tcb_jd"].to_numpy()[order], tr["scan_angle_deg"].to_numpy()[order]
    T, PSI, MASK = np.zeros((n, k)), np.zeros((n, k)), np.zeros((n, k), bool)
    OBS = np.zeros((n, k, 3))
    SAL, SAC = np.ones((n, k)), np.ones((n, k))
    T[star_al, col], PSI[star_al, col], MASK[star_al, col] = t, psi, True
    OBS[star_al, col] = gaia_position_au(t)
    SAL[star_al, col], SAC[star_al, col] = P["s_al"][order], P["s_ac"][order]
    A = design_matrix(P["ra"], P["dec"], (T - P["t_ref"]) / 365.25, PSI, OBS, sigma_al_mas=SAL,
                      sigma_ac_mas=SAC, mask=MASK)
    xt = x_true
    H = np.einsum("nmi,ni->nm", A, xt)
    ac = obs.is_ac
    H[star_al, col] += noise[al][order]
    ac_order = np.argsort(obs.star[ac], kind="stable")
    H[star_al, k + col] += noise[ac][ac_order]  # every transit here has an AC measurement
    sec = solve_with_prior(*normal_equations(A, H), 1.0, 10.0)
    assert ok.all() and sec.ok.all()
    np.testing.assert_allclose(x, sec.x, rtol=RTOL_SECONDARY, atol=RTOL_SECONDARY * np.abs(sec.x).max())
    np.testing.assert_allclose(cov, sec.cov, rtol=RTOL_SECONDARY, atol=RTOL_SECONDARY * np.abs(sec.cov).max())


def test_global_rotation_and_spin_of_truth_leave_errors_unchanged(small_problem):
    P = small_problem
    obs, rng = P["obs"], np.random.default_rng(14)
    x_true, a_true = _truth(P, rng, zero_motion=False)
    # float64 partials: with float32 ones the degeneracy is exact only to their rounding
    problem = GlobalProblem(obs, prior_diagonal(2.0, 10.0), P["ra"], P["dec"], compact=False)
    noise = rng.normal(size=obs.size)
    errors = []
    for eps, omega in (((0, 0, 0), (0, 0, 0)), ((3.0, -2.0, 5.0), (0.4, 0.7, -0.3))):
        x_rot = x_true + frame_offsets(P["ra"], P["dec"], eps, omega)
        h = problem.forward(problem.join(x_rot, a_true)) + noise
        sol = solve_global(problem, h, rtol=1e-12, max_iter=5000)
        assert sol.converged
        dx = sol.x - x_rot
        e, w = fit_frame(dx, P["ra"], P["dec"])
        errors.append(dx - frame_offsets(P["ra"], P["dec"], e, w))
    scale = np.abs(errors[0]).max()
    np.testing.assert_allclose(errors[1], errors[0], rtol=0, atol=RTOL_ITER_DIRECT * scale)


def test_solution_is_bit_identical_for_any_chunking_and_workers(weak_problem, monkeypatch):
    # The promise of mcsweep.solver.reduction: fixed blocks summed in a fixed tree, so the
    # chunk size, the backend, the number of workers and the slabs in which the setup sums
    # the banded Schur block cannot change a bit.
    from mcsweep.solver import schur_preconditioner
    P = weak_problem
    rng = np.random.default_rng(31)
    problem = GlobalProblem(P["obs"], prior_diagonal(1000.0, 10.0), P["ra"], P["dec"], block_stars=128)
    assert len(problem.blocks) > 8
    x_true, a_true = _truth(P, rng, zero_motion=False)
    h = problem.forward(problem.join(x_true, a_true)) + rng.normal(size=P["obs"].size)
    kw = dict(rtol=1e-10, update_tol_uas=1e-3, max_iter=12)  # bit identity needs no convergence
    ref = solve_global(problem, h, **kw)
    runs = [solve_global(problem, h, chunk_stars=c, **kw) for c in (128, 512, 100000)]
    runs += [solve_global(problem, h, workers=w, chunk_stars=c, **kw) for w, c in ((2, 128), (3, 256))]  # forked
    band_bytes = 8 * (schur_bandwidth() + 1) * 3 * problem.n_coef
    monkeypatch.setattr(schur_preconditioner, "SETUP_SLAB_BYTES", band_bytes // 7)  # the band in 8 slabs
    runs += [solve_global(problem, h, chunk_stars=128, **kw), solve_global(problem, h, workers=2, chunk_stars=256, **kw)]
    from mcsweep.solver import resident
    monkeypatch.setattr(resident, "ARENA_MIN_BYTES", 0)  # every buffer through the workers' shared arenas,
    runs += [solve_global(problem, h, workers=2, chunk_stars=128, **kw)]
    monkeypatch.setattr(resident, "ARENA_BYTES", 4096)  # or, past a full arena, through the pipe
    runs += [solve_global(problem, h, workers=2, chunk_stars=128, **kw)]
    for sol in runs:
        assert np.array_equal(sol.x, ref.x) and np.array_equal(sol.attitude, ref.attitude)
        assert np.array_equal(sol.residuals, ref.residuals) and len(sol.history) == len(ref.history)
        assert sol.residual_rms == ref.residual_rms


def test_with_prior_equals_a_problem_built_for_that_prior(weak_problem):
    P = weak_problem
    h = np.random.default_rng(41).normal(size=P["obs"].size)
    a = GlobalProblem(P["obs"], prior_diagonal(1.0, 10.0), P["ra"], P["dec"]).with_prior(prior_diagonal(1000.0, 10.0))
    b = GlobalProblem(P["obs"], prior_diagonal(1000.0, 10.0), P["ra"], P["dec"])
    sa, sb = (solve_global(p, h, rtol=1e-8, max_iter=50) for p in (a, b))
    assert np.array_equal(sa.x, sb.x) and np.array_equal(sa.attitude, sb.attitude)


def test_compact_storage_solves_its_own_normal_equations(weak_problem):
    # float32 spline values: the stored (rounded) partials define the problem solved
    P = weak_problem
    sol, rel = _agreement(P, prior_diagonal(1000.0, 10.0), 21, compact=True)
    assert sol.converged and rel < RTOL_ITER_DIRECT
    full = GlobalProblem(P["obs"], prior_diagonal(1000.0, 10.0), P["ra"], P["dec"])
    small = GlobalProblem(P["obs"], prior_diagonal(1000.0, 10.0), P["ra"], P["dec"], compact=True)
    assert small.nbytes_per_measurement < full.nbytes_per_measurement - 15  # 4 x 4 bytes


def test_weighted_frame_fit_ignores_imprecise_stars(small_problem):
    # A known rotation and spin plus arcsec-level errors on a tenth of the stars, whose
    # weights are 1e-8 of the others': the weighted fit recovers the rotation and spin.
    P = small_problem
    rng = np.random.default_rng(51)
    eps, omega = np.array([0.3, -0.2, 0.5]), np.array([0.04, 0.07, -0.03])
    dx = frame_offsets(P["ra"], P["dec"], eps, omega)
    weak = rng.uniform(size=dx.shape[0]) < 0.1
    dx[weak] += rng.normal(0.0, 3000.0, (int(weak.sum()), 5))
    w = np.where(weak[:, None], 1e-8, 1.0) * np.ones((dx.shape[0], 2))
    e, o = fit_frame(dx, P["ra"], P["dec"], weights=w)
    np.testing.assert_allclose(e, eps, atol=1e-3)
    np.testing.assert_allclose(o, omega, atol=1e-3)
    e0, _ = fit_frame(dx, P["ra"], P["dec"])
    assert np.abs(e0 - eps).max() > 1.0  # unweighted, the imprecise stars set it


@pytest.mark.parametrize("window", [1, 2])  # 1: the solver's SCHUR_WINDOW; 2: the wider clusters
def test_banded_schur_preconditioner_equals_its_dense_definition(weak_problem, window):
    # S_band = sum_i G_i' (I - P_i . [same j0 window]) G_i, P_i = A_i B_i^-1 A_i', star by
    # star with dense matrices (independent of blocks.py's cluster sums), and it is positive
    # semi-definite. A 1 mas prior: under 1000 mas the 5 x 5 blocks have condition ~1e10
    # and the two subtractions agree only to ~1e-8.
    from mcsweep.solver.blocks import schur_absorption

    P = weak_problem
    obs = P["obs"]
    problem = GlobalProblem(obs, prior_diagonal(1.0, 10.0), P["ra"], P["dec"])
    band = -sum(schur_absorption(b, problem.prior[b.first:b.first + b.n], window=window) for b in problem.blocks)
    band[-problem.naa_band.shape[0]:] += problem.naa_band  # N_aa: once per problem
    A = _sparse_design(P).toarray()
    As, G = A[:, :5 * obs.n_stars], A[:, 5 * obs.n_stars:]
    dense = G.T @ G
    for i in range(obs.n_stars):  # a test may loop over stars
        rows = np.flatnonzero(obs.star == i)
        Ai = As[rows, 5 * i:5 * i + 5]
        jw = obs.j0[rows] // window
        Pi = Ai @ problem.src_inv[i] @ Ai.T * (jw[:, None] == jw[None, :])
        dense -= G[rows].T @ Pi @ G[rows]
    np.testing.assert_allclose(band_to_dense(band), dense, rtol=0, atol=RTOL_SUMS * np.abs(dense).max())
    assert np.linalg.eigvalsh(dense).min() > -RTOL_SUMS * np.abs(dense).max()


def _decimal_schur_band(problem, prior, window: int, digits: int = 60) -> np.ndarray:
    """Dense ``sum_i sum_c G_ic' (I - P_i,cc) G_ic`` (clusters: ``window`` first coefficients) of the problem's stored partials,
    in ``digits``-digit decimal arithmetic (star by star, Gauss-Jordan inverse): a reference
    whose rounding (1e-60 x condition ~1e12) is far below double precision's."""
    from decimal import Decimal, localcontext

    star, src, att, j0, bval = problem.design()
    n_att = 3 * problem.n_coef
    out = np.zeros((n_att, n_att))
    with localcontext() as ctx:
        ctx.prec = digits
        D = np.vectorize(Decimal, otypes=[object])
        for i in range(problem.n_stars):  # a test may loop over stars
            rows = np.flatnonzero(star == i)
            A = D(src[rows])  # (m, 5)
            G = np.array([[Decimal(bval[r, k]) * Decimal(att[r, c]) for k in range(4) for c in range(3)]
                          for r in rows], dtype=object)  # (m, 12), unknowns 3 j0 .. 3 j0 + 11
            Bm = A.T @ A + np.diag(D(prior[i]))
            inv = np.array([[Decimal(int(a == b)) for b in range(5)] for a in range(5)], dtype=object)
            M = Bm.copy()
            for k in range(5):  # Gauss-Jordan (B is symmetric positive definite: no pivoting)
                piv = M[k, k]
                M[k], inv[k] = M[k] / piv, inv[k] / piv
                for r in range(5):
                    if r != k:
                        f = M[r, k]
                        M[r], inv[r] = M[r] - f * M[k], inv[r] - f * inv[k]
            jw = j0[rows] // window
            for w in np.unique(jw):
                c = np.flatnonzero(jw == w)
                width = 3 * (window + 3)
                Gw = np.full((c.size, width), Decimal(0), dtype=object)  # the window's unknowns
                for n, r in enumerate(c):
                    o = 3 * (int(j0[rows][r]) - int(w) * window)
                    Gw[n, o:o + 12] = G[r]
                H = A[c].T @ Gw
                S = Gw.T @ Gw - H.T @ inv @ H
                lo = 3 * int(w) * window
                hi = min(lo + width, n_att)
                out[lo:hi, lo:hi] += S.astype(float)[:hi - lo, :hi - lo]
    return out


@pytest.mark.parametrize("window", [1, 2])
def test_banded_schur_block_stays_exact_and_positive_under_a_1000_mas_prior(monkeypatch, window):
    # Stars seen once or twice under 1000 mas: B_i has condition ~1e10-1e12 and the
    # normal-equation form G'G - H'B^-1H loses ~1e-6 of a star's G'G, which at the paper's sizes
    # with AGIS's knots made the band indefinite (docs/notes/table3/prior_1000mas.md). The orthogonal form must
    # match a 60-digit reference to double precision, where the other form does not.
    from tests.solver.conftest import make_problem
    from mcsweep.solver import blocks as B

    P = make_problem(n_stars=40, days=365.0, knot_days=8.0, seed=21, min_transits=1, keep_fraction=0.15)
    obs = P["obs"]
    # 1000 mas, and 1 mas for every third star (each star its own prior; both forms in a band)
    sigma = np.where(np.arange(obs.n_stars) % 3 == 0, 1.0, 1000.0)
    prior = prior_diagonal(sigma, 10.0)
    problem = GlobalProblem(obs, prior, P["ra"], P["dec"])
    assert np.bincount(obs.star).min() <= 4  # stars with <= 2 FoV transits (AL + AC each)

    def band(kappa):
        monkeypatch.setattr(B, "STABLE_ABSORPTION_KAPPA", kappa)
        ab = -sum(B.schur_absorption(b, prior[b.first:b.first + b.n], batch_stars=7, window=window)
                  for b in problem.blocks)  # batches of 7 stars: several per block
        ab[-problem.naa_band.shape[0]:] += problem.naa_band
        return band_to_dense(ab)

    ref = _decimal_schur_band(problem, prior, window)
    scale = np.abs(problem.naa_band).max()
    kappa = B.STABLE_ABSORPTION_KAPPA
    orthogonal, normal = band(kappa), band(np.inf)
    err_orthogonal = np.abs(orthogonal - ref).max() / scale
    err_normal = np.abs(normal - ref).max() / scale
    print(f"max error / max |N_aa|: orthogonal {err_orthogonal:.1e}, normal equations {err_normal:.1e}; "
          f"smallest eigenvalue / max |N_aa|: {np.linalg.eigvalsh(orthogonal).min() / scale:.1e}, "
          f"{np.linalg.eigvalsh(normal).min() / scale:.1e}, reference {np.linalg.eigvalsh(ref).min() / scale:.1e}")
    assert err_orthogonal < RTOL_SUMS
    assert err_normal > 1e3 * err_orthogonal  # the reason for the orthogonal form
    assert np.linalg.eigvalsh(orthogonal).min() > -RTOL_SUMS * scale


@pytest.mark.parametrize("window", [1, 2])
def test_slabs_of_the_schur_absorption_side_by_side_are_the_whole_band_bit_for_bit(window):
    # The setup sums the absorption slab by slab of the band's columns (memory at AGIS's
    # knots); each slab must hold exactly the whole band's elements, for stars of either form
    # (1 and 1000 mas priors mixed), cuts anywhere (inside a cluster's window too) and batches
    # of stars that split the blocks.
    from tests.solver.conftest import make_problem
    from mcsweep.solver import blocks as B

    P = make_problem(n_stars=40, days=365.0, knot_days=8.0, seed=21, min_transits=1, keep_fraction=0.15)
    obs = P["obs"]
    prior = prior_diagonal(np.where(np.arange(obs.n_stars) % 3 == 0, 1.0, 1000.0), 10.0)
    problem = GlobalProblem(obs, prior, P["ra"], P["dec"])
    n_att = 3 * problem.n_coef
    for b in problem.blocks:
        pr = prior[b.first:b.first + b.n]
        assert 0 < B.ill_conditioned(b).sum() < b.n  # both forms present
        whole = B.schur_absorption(b, pr, batch_stars=7, window=window)
        for cuts in ([0, n_att], [0, 1, 5, 17, n_att // 2 + 1, n_att], list(range(0, n_att, 7)) + [n_att]):
            slabs = [B.schur_absorption(b, pr, batch_stars=7, window=window, columns=c) for c in zip(cuts[:-1], cuts[1:])]
            assert np.concatenate(slabs, axis=1).tobytes() == whole.tobytes()


@pytest.mark.parametrize("compact", [False, True])
def test_compiled_preconditioner_sweeps_equal_sparse_products(weak_problem, compact):
    # mcsweep.solver.kernels (the PCG's hot path) against the same products formed with the
    # sparse design matrix of the stored partials (independent of blocks.py and kernels.py)
    from mcsweep.solver import kernels

    P = weak_problem
    problem = GlobalProblem(P["obs"], prior_diagonal(1.0, 10.0), P["ra"], P["dec"], block_stars=512,
                            compact=compact)
    A = _sparse_design(P, problem).tocsr()
    n5 = problem.n_src
    A_s, A_a = A[:, :n5], A[:, n5:]
    rng = np.random.default_rng(71)
    r_s, z_a = rng.normal(size=(problem.n_stars, 5)), rng.normal(size=(problem.n_coef, 3))
    binv = problem.src_inv
    y = np.einsum("nij,nj->ni", binv, r_s)
    fwd = A_a.T @ (A_s @ y.ravel())
    u = A_a @ z_a.ravel()
    w = r_s - (A_s.T @ u).reshape(-1, 5)
    z_s = np.einsum("nij,nj->ni", binv, w)
    got_f, got_zs, got_ys, got_ya = np.zeros(problem.n_att), [], [], np.zeros(problem.n_att)
    for b in problem.blocks:
        rows = slice(b.first, b.first + b.n)
        got_f += kernels.precondition_forward(b, y[rows]).ravel()
        zs, ys, ya = kernels.precondition_back(b, r_s[rows], z_a)
        got_zs.append(zs)
        got_ys.append(ys.ravel())
        got_ya += ya.ravel()
    got_zs = np.concatenate(got_zs)
    np.testing.assert_allclose(got_f, fwd, rtol=0, atol=RTOL_SUMS * np.abs(fwd).max())
    # z_s = B^-1 w: rounding of w (other summation order) grows with each star's |B^-1|
    # (condition up to ~1e10 for a star seen once under a loose prior)
    scale = np.abs(binv).max(axis=(1, 2)) * np.abs(w).max(axis=1)
    assert np.all(np.abs(got_zs - z_s).max(axis=1) <= RTOL_SUMS * 5 * scale)
    f = u + A_s @ got_zs.ravel()  # the last products, from the kernel's own z_s
    # f cancels (|u| and |A_s z_s| are up to ~500 x |f|), so each product's rounding is
    # relative to the size of its summands (the forward error bound of a sum, Higham 2002,
    # Sect. 4.2), not to the largest result: 3e-16 of it measured (numpy 2.4, scipy 1.17)
    summands = np.abs(u) + abs(A_s) @ np.abs(got_zs.ravel())
    for got, want, design in ((np.concatenate(got_ys), A_s.T @ f, A_s), (got_ya, A_a.T @ f, A_a)):
        np.testing.assert_array_less(np.abs(got - want), RTOL_SUMS * (abs(design).T @ summands) + 1e-300)


def test_compiled_band_scatter_has_the_bits_of_one_bincount_per_band_element():
    # kernels.band_scatter replaced, in the attitude band and the Schur absorption, a
    # numpy.bincount over all attitude unknowns per band element (3 s per block at 30 s
    # knots); it promises the same bits, so no solution changed with it.
    from mcsweep.solver.kernels import band_scatter

    rng = np.random.default_rng(4)
    L, n_coef, nc = 12, 400, 3000
    H, BH = (rng.normal(size=(5, L, nc)) * 10.0 ** rng.uniform(-6, 6, (1, 1, nc)) for _ in range(2))
    base = 3 * rng.integers(0, n_coef, nc)  # repeated unknowns, unsorted, some past the end

    def by_bincount(ab):
        for r in range(L):
            for c in range(r, L):
                w = H[0, r] * BH[0, c]
                for i in range(1, 5):
                    w += H[i, r] * BH[i, c]
                ab[L - 1 + r - c] += np.bincount(base + c, w, minlength=3 * n_coef)[:3 * n_coef]

    ref, got = np.zeros((L, 3 * n_coef)), np.zeros((L, 3 * n_coef))
    for _ in range(2):  # into zeros, then on top (a second block of a leaf)
        by_bincount(ref)
        band_scatter(got, H, BH, base)
        assert np.array_equal(got, ref)


def test_the_design_of_a_problem_of_several_blocks_names_every_measurement_s_own_star():
    """``GlobalProblem.design`` against the observations it was built from, with more stars
    than one block's int16 indices reach (found at 3 x 1e5 stars: the second block's first
    star, 32768, overflowed int16)."""
    from tests.solver.conftest import make_problem

    P = make_problem(n_stars=200000, days=10.0, knot_days=0.5, min_transits=1)
    obs = P["obs"]
    assert obs.n_stars > SOLVER_BLOCK_STARS
    problem = GlobalProblem(obs, prior_diagonal(np.full(obs.n_stars, 1.0), 10.0), P["ra"], P["dec"])
    assert len(problem.blocks) == 2
    star, src, att, j0, bval = problem.design()
    np.testing.assert_array_equal(star, obs.star)
    np.testing.assert_array_equal(j0, obs.j0)
    np.testing.assert_array_equal(src, obs.src)
