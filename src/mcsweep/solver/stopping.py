"""When the PCG iteration of :func:`~mcsweep.solver.solve.solve_global` stops, and what it
records of each iteration.

Energy criterion (``error_tol`` given, as the experiments do): PCG stops when the error of
the solution in the norm of the normal matrix, ``|x - x*|_N = sqrt((x - x*)' N (x - x*))``,
is estimated to be below ``error_tol``. For any linear function ``g'x`` of the unknowns (a
star's position, an attitude coefficient, a frame-free combination), Cauchy-Schwarz gives
``|g'(x - x*)| <= sqrt(g' N^-1 g) |x - x*|_N``, and ``sqrt(g' N^-1 g)`` is the formal standard
error of ``g'x``. So ``error_tol = 0.01`` means that no estimated quantity is off the exact
least-squares solution by more than 1 % of its own formal uncertainty, a bright star's
position known to 10 uas as much as an attitude knot seen only by faint stars, known to a
few mas; ``|x - x*|_N^2`` is the chi-square the truncation adds. An absolute update
tolerance (below) treats those two alike, and weakly determined knots keep it unmet long
after the stars have stopped moving.

The estimate. The steps of CG are N-orthogonal, so the squared error of iterate ``x_k`` is
the sum of the squared N-norms of all later steps, ``|x* - x_k|_N^2 = sum_{i > k} s_i`` with
``s_i = alpha_i r_{i-1}' z_{i-1}`` (Hestenes & Stiefel 1952, J. Res. NBS 49, 409; Strakos &
Tichy 2002, ETNA 13, 56, show that this holds in finite precision too). The remaining sum is
extrapolated from the last :data:`ERROR_WINDOW` steps as a geometric series,
``s_k q / (1 - q)`` with ``q = (s_k / s_{k-w})^(1/w)`` (infinite while the steps do not fall),
and multiplied by :data:`ERROR_SAFETY`, a margin on the largest under-estimate measured
(docs/solver_design.md, "Convergence criterion"). From a starting attitude the first step
also moves the stars from zero to their update, a one-off left out of the window.

Otherwise (``error_tol=None``) it stops after iteration ``k >= min_iter`` when both the
relative residual of the normal equations ``|b - N x| / |b| < rtol`` (recursively updated;
from a starting attitude ``|b - N x| / |b - N x0|``) and the largest change of any unknown
in that iteration (mas or mas/yr) is below ``update_tol_uas`` microarcseconds. Either way it
stops after ``max_iter`` iterations (then ``converged = False``). Every iteration is
recorded (:class:`ConvergenceRecord`).
"""

from __future__ import annotations

import dataclasses
import math

__all__ = ["ConvergenceRecord", "remaining_error", "ERROR_WINDOW", "ERROR_SAFETY", "UAS_PER_MAS"]

UAS_PER_MAS = 1000.0
#: Steps whose mean decrease extrapolates the error of the energy criterion (module notes).
ERROR_WINDOW = 10
#: Factor on the extrapolated error: the largest under-estimate measured from 10 steps, 2.03,
#: with a margin (docs/solver_design.md, "Convergence criterion").
ERROR_SAFETY = 2.5


@dataclasses.dataclass
class ConvergenceRecord:
    """One iteration: update norms [microarcsec], residual RMS, relative residual, wall time;
    ``energy_decrease`` the step's squared N-norm (``alpha r'z``), ``error_estimate`` the
    estimated ``|x* - x|_N`` after it (NaN for the first ``ERROR_WINDOW`` iterations and
    without ``error_tol``; module notes)."""

    iteration: int
    update_max_uas: float
    update_rms_position_uas: float
    update_rms_attitude_uas: float
    residual_rms: float
    relative_residual: float
    seconds: float
    energy_decrease: float = float("nan")
    error_estimate: float = float("nan")


def remaining_error(steps) -> float:
    """``ERROR_SAFETY`` times the error ``|x* - x_k|_N`` extrapolated from the squared N-norms
    ``steps`` of the steps so far (module notes); NaN before ``ERROR_WINDOW + 1`` steps,
    infinite while they do not fall."""
    if len(steps) <= ERROR_WINDOW:
        return float("nan")
    last, first = steps[-1], steps[-1 - ERROR_WINDOW]
    if not 0.0 < last < first:
        return 0.0 if last == 0.0 else float("inf")
    q = (last / first) ** (1.0 / ERROR_WINDOW)
    return ERROR_SAFETY * math.sqrt(last * q / (1.0 - q))
