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
from mcsweep.solver.calibration import MAX_ROUNDS, basic_angle_columns, solve_with_calibration
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
    # variation in the data; reference: the bordered normal equations solved directly.
    P = gapped_problem
    obs, rng = P["obs"], np.random.default_rng(3)
    n = obs.n_stars
    cols = _columns(P, harmonics)
    E = np.column_stack([cols.column(k) for k in range(cols.n_cal)])
    x_true = np.column_stack([rng.normal(0, 5, n), rng.normal(0, 5, n), rng.uniform(0.2, 3.0, n),
                              rng.normal(0, 5, n), rng.normal(0, 5, n)])
    problem = GlobalProblem(obs, prior_diagonal(sigma_mas, 10.0), P["ra"], P["dec"])
    h = (problem.forward(problem.join(x_true, rng.normal(0, 10.0, (obs.n_coef, 3)))) + rng.normal(size=obs.size)
         + E @ rng.normal(0, 1.0, cols.n_cal))
    cal = solve_with_calibration(
        lambda hh, log, scale: solve_global(problem, hh, error_tol=ERROR_TOL * scale, max_iter=1000, residuals=True),
        h, cols)
    direct, free, _ = solve_direct(problem, h, extra_columns=E)
    ours = np.concatenate([problem.join(cal.solution.x, cal.solution.attitude)[free], cal.c])
    err = normal_norm(problem, ours - direct, E)
    print(f"{sigma_mas} mas, {harmonics} harmonic(s): iterations {cal.iterations}, condition {cal.condition:.3g}, "
          f"amplification {cal.amplification:.3g}, "
          f"|x - x*|_N = {err:.2e}")
    assert cal.solution.converged and 1 + 2 * harmonics <= len(cal.iterations) <= MAX_ROUNDS * (1 + 2 * harmonics)
    assert err <= ERROR_TOL
    resid = h - problem.forward(problem.join(cal.solution.x, cal.solution.attitude)) - E @ cal.c
    np.testing.assert_allclose(cal.solution.residuals, resid, rtol=0, atol=1e-9 * np.abs(h).max())


def _fake(factor, tightening=False):
    """A solution that leaves ``factor`` of every right-hand side as residual (with
    ``tightening``, times the tolerance's ``scale``: finer solutions that fit less)."""
    from mcsweep.solver.cg import GlobalSolution

    def solve(h, log, scale):
        return GlobalSolution(x=np.zeros((1, 5)), attitude=np.zeros((1, 3)), cov=np.zeros((1, 5, 5)),
                              residuals=factor * (scale if tightening else 1.0) * h, residual_rms=0.0, history=[],
                              converged=True)
    return solve


@pytest.mark.parametrize("factor", [-1e-12, 0.0, 1e-13])
def test_a_calibration_the_data_do_not_fix_is_an_error_not_a_solution(factor):
    # A column the rest of the design takes up entirely leaves S = 0 (with the solutions'
    # rounding slightly negative or positive): no accuracy can be promised and the solution stops.
    from mcsweep.solver.calibration import BasicAngleColumns, CalibrationNotDetermined

    rng = np.random.default_rng(1)
    cols = BasicAngleColumns(omega=rng.uniform(0, 2 * np.pi, 50), weight=rng.normal(size=50), harmonics=1)
    with pytest.raises(CalibrationNotDetermined, match="not determined by the data"):
        solve_with_calibration(_fake(factor), np.ones(50), cols)


def test_rounds_that_cannot_reach_the_accuracy_end_the_solution():
    # Solutions whose calibration grows as they are asked for a finer tolerance (a column the
    # rest of the design nearly takes up): the columns are made again until MAX_ROUNDS, then
    # it stops rather than return a solution whose error bound is not met.
    from mcsweep.solver.calibration import BasicAngleColumns, CalibrationNotDetermined

    rng = np.random.default_rng(2)
    cols = BasicAngleColumns(omega=rng.uniform(0, 2 * np.pi, 50), weight=rng.normal(size=50), harmonics=1)
    h = 10.0 * cols.column(0)
    with pytest.raises(CalibrationNotDetermined, match=f"in {MAX_ROUNDS} rounds"):
        solve_with_calibration(_fake(0.5, tightening=True), h, cols)
    done = solve_with_calibration(_fake(0.5), h, cols, scalable=False)  # the absolute rule: solved once each
    assert done.iterations == [0, 0, 0] and abs(done.c[0] - 10.0) < 1e-9
