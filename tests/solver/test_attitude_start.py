"""PCG from a starting attitude (``solve_global(..., attitude_start=)``): the solution is the
least-squares one to the asked fraction of its uncertainties wherever it starts, checked
against a direct sparse solve of the same normal equations on the few-transits-per-knot
problem with data gaps (conftest ``gapped_system``); a start near the solution takes fewer
iterations than zero; the bits do not depend on the workers."""

from __future__ import annotations

import numpy as np
import pytest

from mcsweep.astrometry.solve import prior_diagonal
from mcsweep.solver import GlobalProblem, solve_global
from mcsweep.solver.stopping import ERROR_WINDOW
from mcsweep.solver.direct import normal_norm, solve_direct

#: The solutions' stopping rule: error below this fraction of the formal uncertainties.
ERROR_TOL = 0.01


@pytest.mark.parametrize("sigma_mas", [0.01, 1.0, 1000.0])
def test_a_solution_started_from_another_priors_attitude_is_the_direct_solution(gapped_system, sigma_mas):
    # The experiment's chain (experiment.primary.solver_start='previous'): the attitude of the
    # same data solved under a prior 10 times tighter, as sigma_F90 before 10 sigma_F90.
    problem, h = gapped_system(sigma_mas)
    tighter, _ = gapped_system(sigma_mas / 10)
    start = solve_global(tighter, h, error_tol=ERROR_TOL, max_iter=1000).attitude
    direct, free, _ = solve_direct(problem, h)
    cold = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, residuals=False)
    warm = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, attitude_start=start)
    err = normal_norm(problem, problem.join(warm.x, warm.attitude)[free] - direct)
    moved = normal_norm(problem, problem.join(np.zeros_like(warm.x), start)[free] - direct)
    print(f"{sigma_mas} mas: {len(warm.history)} iterations from the tighter prior's attitude (|x0 - x*|_N = "
          f"{moved:.3g}), {len(cold.history)} from zero; |x - x*|_N = {err:.2e}")
    assert warm.converged and err <= ERROR_TOL
    assert len(warm.history) < len(cold.history)
    # the first step (the stars from zero) is left out of the error's extrapolation
    assert np.isnan(warm.history[ERROR_WINDOW].error_estimate) and not np.isnan(cold.history[ERROR_WINDOW].error_estimate)
    # residuals and their RMS are those of the whole solution, start included
    resid = h - problem.forward(problem.join(warm.x, warm.attitude))
    np.testing.assert_allclose(warm.residuals, resid, rtol=0, atol=1e-9 * np.abs(h).max())
    assert warm.residual_rms == pytest.approx(float(np.sqrt(np.mean(resid ** 2))), rel=1e-9)
    assert warm.history[-1].residual_rms == pytest.approx(warm.residual_rms, rel=1e-6)


def test_a_start_at_the_solution_is_kept(gapped_system):
    # From the exact attitude the stars follow in the first step; what PCG adds is below the
    # asked accuracy, so the start is not lost (a start applied twice, or with the wrong
    # sign, would be off by |a*|_N).
    problem, h = gapped_system(1.0)
    direct, free, _ = solve_direct(problem, h)
    exact = np.zeros(problem.size)
    exact[free] = direct
    _, a_star = problem.split(exact)
    sol = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, attitude_start=a_star)
    err = normal_norm(problem, problem.join(sol.x, sol.attitude)[free] - direct)
    scale = normal_norm(problem, problem.join(np.zeros((problem.n_stars, 5)), a_star)[free])
    assert sol.converged and err <= ERROR_TOL < scale


def test_a_started_solution_is_the_same_bits_with_forked_workers(gapped_problem):
    P = gapped_problem
    problem = GlobalProblem(P["obs"], prior_diagonal(1.0, 10.0), P["ra"], P["dec"], block_stars=128)
    rng = np.random.default_rng(5)
    h = rng.normal(size=P["obs"].size)
    start = rng.normal(0, 1.0, (problem.n_coef, 3))
    one = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, attitude_start=start)
    two = solve_global(problem, h, error_tol=ERROR_TOL, max_iter=1000, attitude_start=start, workers=2,
                       chunk_stars=128)
    assert len(one.history) == len(two.history)
    np.testing.assert_array_equal(one.x, two.x)
    np.testing.assert_array_equal(one.attitude, two.attitude)


def test_a_start_of_another_shape_is_refused(gapped_system):
    problem, h = gapped_system(1.0)
    with pytest.raises(ValueError, match=r"attitude_start has shape \(3, 3\)"):
        solve_global(problem, h, error_tol=ERROR_TOL, attitude_start=np.zeros((3, 3)))
