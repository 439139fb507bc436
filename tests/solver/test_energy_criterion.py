"""The energy criterion of the global solver (module notes of :mod:`mcsweep.solver.stopping`):
PCG stops when the error in the norm of the normal matrix is estimated below a fraction of
the formal uncertainties. Checked against a direct sparse solve of the same normal
equations, on the few-transits-per-knot problem with data gaps (conftest ``gapped_system``)."""

from __future__ import annotations

import numpy as np
import pytest

from mcsweep.solver import solve_global
from mcsweep.solver.direct import normal_norm, solve_direct
from mcsweep.solver.stopping import ERROR_SAFETY, ERROR_WINDOW, remaining_error


@pytest.mark.parametrize("sigma_mas", [0.01, 1.0, 1000.0])
def test_the_solution_is_within_the_asked_fraction_of_its_uncertainties(gapped_system, sigma_mas):
    problem, h = gapped_system(sigma_mas)
    direct, free, _ = solve_direct(problem, h)
    scale = normal_norm(problem, direct)  # |x*|_N: the error of the starting point x = 0
    for tol in (1.0, 0.01):
        sol = solve_global(problem, h, error_tol=tol, max_iter=500)
        err = normal_norm(problem, problem.join(sol.x, sol.attitude)[free] - direct)
        print(f"{sigma_mas} mas, error_tol {tol}: {len(sol.history)} iterations, |x - x*|_N = {err:.2e} "
              f"(|x*|_N = {scale:.2e})")
        assert sol.converged and err <= tol
        assert sol.history[-1].error_estimate <= tol and not sol.history[-2].error_estimate <= tol
        assert np.isnan(sol.history[ERROR_WINDOW - 1].error_estimate)


def test_the_steps_add_up_to_the_error_they_remove(gapped_system):
    # The steps are N-orthogonal: the squared N-norms logged for steps k+1..k+d add up to
    # |x_{k+d} - x_k|_N^2, a lower bound of |x* - x_k|_N^2 (what the estimate extrapolates).
    problem, h = gapped_system(1.0)
    direct, free, _ = solve_direct(problem, h)
    k, d = 30, 20
    early = solve_global(problem, h, error_tol=1e-300, max_iter=k)
    err_k = normal_norm(problem, problem.join(early.x, early.attitude)[free] - direct)
    full = solve_global(problem, h, error_tol=1e-300, max_iter=k + d)
    step_sum = np.sqrt(sum(r.energy_decrease for r in full.history[k:]))
    steps_norm = normal_norm(problem, problem.join(full.x - early.x, full.attitude - early.attitude)[free])
    print(f"x_{k}: error {err_k:.4e}, next {d} steps {step_sum:.4e}, |x_{k + d} - x_{k}|_N {steps_norm:.4e}, "
          f"estimate {early.history[-1].error_estimate:.4e}")
    assert not early.converged and not full.converged
    assert step_sum == pytest.approx(steps_norm, rel=1e-6)
    assert step_sum <= err_k * (1 + 1e-9)
    assert early.history[-1].error_estimate >= err_k


def test_the_extrapolation_of_a_geometric_series():
    q, c = 0.7, 3.0
    steps = list(c * q ** np.arange(1, 16))
    exact = np.sqrt(steps[-1] * q / (1 - q))  # sum_{i > 15} c q^i
    assert remaining_error(steps) == pytest.approx(ERROR_SAFETY * exact, rel=1e-12)
    assert np.isnan(remaining_error(steps[:ERROR_WINDOW]))
    assert remaining_error(steps[:-1] + [steps[-ERROR_WINDOW - 1]]) == np.inf  # no decrease: no stop


def test_the_residual_criterion_is_kept_when_asked(gapped_system):
    problem, h = gapped_system(1.0)
    sol = solve_global(problem, h, rtol=1e-10, update_tol_uas=1e-3, max_iter=500)
    assert sol.converged
    last = sol.history[-1]
    assert last.relative_residual < 1e-10 and last.update_max_uas < 1e-3 and np.isnan(last.error_estimate)
    with pytest.raises(ValueError, match="error_tol"):
        solve_global(problem, h, error_tol=0.0)
