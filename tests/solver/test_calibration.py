"""A basic-angle variation solved with the stars and the attitude (:mod:`mcsweep.solver.calibration`):
its design against the published degeneracy with the parallax zero point, and the bordered
solution against a direct sparse solve of the same normal equations."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from mcsweep.astrometry.solve import prior_diagonal
from mcsweep.scanning.ephemeris import gaia_position_au
from mcsweep.solver import GlobalProblem, solve_global
from mcsweep.solver.calibration import (BasicAngleColumns, CalibrationNotDetermined, basic_angle_columns,
                                        calibration_design)
from mcsweep.solver.direct import normal_norm, solve_direct, sparse_design

from .conftest import LAW, make_problem

#: The solutions' stopping rule: error below this fraction of the formal uncertainties.
ERROR_TOL = 0.01


def _columns(P, harmonics):
    """The calibration design of a conftest problem: its AL rows are its transits in order."""
    obs, tr = P["obs"], P["transits"]
    k = len(tr)
    following = np.zeros(obs.size, bool)
    following[:k] = tr["fov"].astype(str).to_numpy() == "F"
    sigma = np.ones(obs.size)
    sigma[:k] = P["s_al"]
    return basic_angle_columns(obs.tcb_jd, following, sigma, obs.is_ac, LAW, harmonics)


def _fit_fraction(M, g):
    """|g - M theta| / |g| for the least-squares theta (a tiny ridge for attitude columns
    the span leaves without data)."""
    theta = spsolve((M.T @ M).tocsc() + 1e-12 * sp.identity(M.shape[1], format="csc"), M.T @ g)
    return np.linalg.norm(g - M @ theta) / np.linalg.norm(g), theta


def test_a_shift_of_every_parallax_is_a_basic_angle_variation():
    # Butkevich et al. (2017, A&A 603, A45): a shift d plx of every parallax moves each AL
    # measurement by -d plx |b| sin xi sin(Omega +- Gamma/2) (b the observer's barycentric
    # distance in au): the part common to both fields is an attitude rotation, the difference
    # a basic-angle variation -2 d plx |b| sin xi sin(Gamma/2) cos Omega, with Omega the
    # heliotropic spin phase. So the parallax column of the design lies in the span of the
    # attitude and of the variation's cos Omega column, not of the attitude alone, when the
    # spline follows the 6 h spin period (30 min knots here).
    P = make_problem(n_stars=1500, days=30.0, knot_days=1 / 48, seed=21, min_transits=1)
    obs = P["obs"]
    problem = GlobalProblem(obs, prior_diagonal(1.0, 10.0), P["ra"], P["dec"])
    A = sparse_design(*problem.design(), problem.n_stars, problem.n_coef)
    g = problem.design()[1][:, 2]  # d(measurement) / d(parallax) of each measurement's own star
    att = A[:, 5 * problem.n_stars:]
    att = att[:, np.asarray(abs(att).sum(axis=0)).ravel() > 0]
    cols = _columns(P, 1)
    C = sp.csr_matrix(np.column_stack([cols.column(0), cols.column(1)]))
    alone, _ = _fit_fraction(att, g)
    both, theta = _fit_fraction(sp.hstack([att, C]).tocsr(), g)
    print(f"parallax column left over: attitude alone {alone:.4f}, with the variation {both:.2e}; "
          f"cos / sin coefficients {theta[-2]:.5f} / {theta[-1]:.2e}")
    assert alone > 0.1 and both < 3e-3
    # its size: 2 |b| sin xi sin(Gamma / 2) per unit parallax, |b| over the 30 days
    b = np.linalg.norm(gaia_position_au(obs.tcb_jd), axis=-1)
    unit = 2 * math.sin(math.radians(LAW.solar_aspect_deg)) * math.sin(math.radians(LAW.basic_angle_deg / 2))
    assert unit * b.min() * (1 - 3e-3) <= abs(theta[-2]) <= unit * b.max() * (1 + 3e-3)
    assert abs(theta[-1]) < 1e-2 * abs(theta[-2])  # Omega is measured from the Sun's direction


@pytest.mark.parametrize("harmonics", [1, 2])
@pytest.mark.parametrize("sigma_mas", [0.01, 1.0, 1000.0])
def test_the_calibrated_solution_is_the_direct_solution(gapped_problem, sigma_mas, harmonics):
    # The gapped one-year problem (dead time, ~12 FoV transits per knot) with a true
    # variation in the data; reference: the bordered normal equations solved directly. The
    # calibration borders the one PCG solution (module notes of mcsweep.solver.pcg): its
    # rank-2k change of the preconditioned matrix costs at most 2k more iterations than the
    # same data without it (exact arithmetic; measured: 0-2).
    P = gapped_problem
    obs, rng = P["obs"], np.random.default_rng(3)
    n = obs.n_stars
    cols = _columns(P, harmonics)
    E = calibration_design(cols)
    x_true = np.column_stack([rng.normal(0, 5, n), rng.normal(0, 5, n), rng.uniform(0.2, 3.0, n),
                              rng.normal(0, 5, n), rng.normal(0, 5, n)])
    problem = GlobalProblem(obs, prior_diagonal(sigma_mas, 10.0), P["ra"], P["dec"])
    h = (problem.forward(problem.join(x_true, rng.normal(0, 10.0, (obs.n_coef, 3)))) + rng.normal(size=obs.size)
         + E @ rng.normal(0, 1.0, cols.n_cal))
    sol = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, residuals=True, border=E)
    plain = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, residuals=False)
    direct, free, _ = solve_direct(problem, h, extra_columns=E)
    ours = np.concatenate([problem.join(sol.x, sol.attitude)[free], sol.border])
    err = normal_norm(problem, ours - direct, E)
    print(f"{sigma_mas} mas, {harmonics} harmonic(s): iterations {len(sol.history)} (without the calibration "
          f"{len(plain.history)}), |x - x*|_N = {err:.2e}")
    assert sol.converged and len(sol.history) <= len(plain.history) + 2 * cols.n_cal
    assert err <= ERROR_TOL
    resid = h - problem.forward(problem.join(sol.x, sol.attitude)) - E @ sol.border
    np.testing.assert_allclose(sol.residuals, resid, rtol=0, atol=1e-9 * np.abs(h).max())
    rms = float(np.sqrt(np.mean(resid ** 2)))
    assert sol.residual_rms == pytest.approx(rms, rel=1e-9)
    # the iteration's recursive residual RMS (the last log line) is the explicit one's
    assert sol.history[-1].residual_rms == pytest.approx(rms, rel=1e-6)


def test_a_bordered_solution_from_a_starting_attitude_is_the_direct_solution(gapped_problem):
    # The start's share of the border's right-hand side (C'A_a a0) is taken off with the
    # stars' and the attitude's; a start the calibration's rows missed would leave the fitted
    # terms off by the start's projection on them.
    P = gapped_problem
    obs, rng = P["obs"], np.random.default_rng(4)
    E = calibration_design(_columns(P, 1))
    problem = GlobalProblem(obs, prior_diagonal(1.0, 10.0), P["ra"], P["dec"])
    h = (problem.forward(problem.join(np.zeros((obs.n_stars, 5)), rng.normal(0, 10.0, (obs.n_coef, 3))))
         + rng.normal(size=obs.size) + E @ np.array([2.0, -1.0]))
    start = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000).attitude  # without the calibration
    sol = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, border=E, attitude_start=start)
    direct, free, _ = solve_direct(problem, h, extra_columns=E)
    err = normal_norm(problem, np.concatenate([problem.join(sol.x, sol.attitude)[free], sol.border]) - direct, E)
    assert sol.converged and err <= ERROR_TOL


def test_the_bordered_solution_is_the_same_bits_with_forked_workers(gapped_problem):
    # The bordered columns' star rows live with the chunks: two forked workers hold them as
    # the in-process run does, summed in the same fixed tree.
    P = gapped_problem
    cols = _columns(P, 1)
    E = calibration_design(cols)
    problem = GlobalProblem(P["obs"], prior_diagonal(1.0, 10.0), P["ra"], P["dec"], block_stars=128)
    h = np.random.default_rng(5).normal(size=P["obs"].size) + 3.0 * E[:, 0]
    one = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, border=E)
    two = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, border=E, workers=2, chunk_stars=128)
    assert len(one.history) == len(two.history)
    np.testing.assert_array_equal(one.x, two.x)
    np.testing.assert_array_equal(one.attitude, two.attitude)
    np.testing.assert_array_equal(one.border, two.border)


def test_a_calibration_without_measurements_is_an_error_not_a_solution():
    # Columns no measurement sees (every row AC, weight zero) cannot be solved: their normal
    # matrix is singular, and the solution stops before it starts.
    rng = np.random.default_rng(1)
    cols = BasicAngleColumns(omega=rng.uniform(0, 2 * np.pi, 50), weight=np.zeros(50), harmonics=1)
    with pytest.raises(CalibrationNotDetermined, match="not determined by the measurements"):
        calibration_design(cols)
    # a spin phase sampled at one value leaves the sin and cos terms one combination
    cols = BasicAngleColumns(omega=np.full(50, 0.3), weight=rng.normal(size=50), harmonics=1)
    with pytest.raises(CalibrationNotDetermined, match="condition number"):
        calibration_design(cols)
