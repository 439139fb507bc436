"""The global normal equations solved directly: the reference for the iterative solver.

Independent of the PCG machinery (:mod:`.pcg`, :mod:`.blocks`, :mod:`.reduction`): the
design matrix is assembled element by element as a scipy.sparse matrix from the partials,
the prior (Eq. 18) added on the source diagonal, and the frame constraint (:mod:`.problem`,
:mod:`.frame`) appended as a bordered (KKT) system, so the rank-6 penalty is never
formed densely. The bordered matrix is equilibrated, factorised once (SuperLU through
:func:`scipy.sparse.linalg.splu`) and the solution refined by two steps of iterative
refinement. Memory grows with the fill-in of the factorisation: tests and benchmarks only.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["sparse_design", "solve_direct", "normal_norm"]

#: Iterative-refinement steps after the LU solve (each costs one product and one solve).
REFINEMENT_STEPS = 2


def sparse_design(star, src, att, j0, bval, n_stars: int, n_coef: int) -> sp.csr_matrix:
    """The design matrix (m, 5 n_stars + 3 n_coef) from the partials of every measurement.

    ``star`` (m,), ``src`` (m, 5), ``att`` (m, 3) axis partials, ``j0`` (m,) first
    B-spline coefficient, ``bval`` (m, 4) spline values; unknowns ordered as five source
    parameters per star, then three axes per attitude coefficient.
    """
    star, j0 = np.asarray(star), np.asarray(j0)
    m = star.size
    rows = np.concatenate([np.repeat(np.arange(m), 5), np.repeat(np.arange(m), 12)])
    cols = np.concatenate([(5 * star[:, None] + np.arange(5)).ravel(),
                           (5 * n_stars + 3 * (j0[:, None, None] + np.arange(4)[None, :, None])
                            + np.arange(3)[None, None, :]).ravel()])
    vals = np.concatenate([np.asarray(src, float).ravel(),
                           (np.asarray(bval, float)[:, :, None] * np.asarray(att, float)[:, None, :]).ravel()])
    return sp.csr_matrix((vals, (rows, cols)), shape=(m, 5 * n_stars + 3 * n_coef))


def solve_direct(problem, h, extra_columns=None) -> tuple[np.ndarray, np.ndarray, sp.csr_matrix]:
    """Direct solution of ``problem`` (a :class:`~.problem.GlobalProblem`) for measurements ``h``.

    ``extra_columns`` (m, k): further unknowns without prior or frame constraint, their
    normalised partials (the calibration of :mod:`.calibration`), solved with the rest and
    returned after them in ``x`` (and ``A``).

    Returns
    -------
    x : ndarray
        The unknowns that are not held at zero (``free``), in the order of
        :meth:`GlobalProblem.join`.
    free : ndarray of bool
        Which unknowns ``x`` holds (attitude coefficients without data are left out).
    A : scipy.sparse.csr_matrix
        The design matrix restricted to ``free`` (for other reference solvers, e.g. lsqr).
    """
    n = problem.n_stars
    A, free = _free_design(problem, extra_columns)
    nf = A.shape[1]
    N = (A.T @ A).tocsc() + sp.diags(np.concatenate([problem.prior.ravel(), np.zeros(nf - 5 * n)]))
    C, W = _frame_rows(problem, nf)
    kkt = sp.bmat([[N, sp.csr_matrix(C).T], [sp.csr_matrix(C), -W]]).tocsc()
    rhs = np.concatenate([A.T @ h, np.zeros(6)])
    d = 1.0 / np.sqrt(np.abs(kkt.diagonal()))
    # The bordered matrix is symmetric quasi-definite (N positive definite, -W negative
    # definite), which factorises stably without pivoting (Vanderbei 1995, SIAM J. Optim. 5,
    # 100): symmetric mode with a symmetric ordering. SuperLU's default partial pivoting and
    # column ordering filled a 1500-star, one-year problem with 5500 attitude unknowns so
    # much that it ran for more than 300 s (symmetric mode: 20 s).
    lu = splu((sp.diags(d) @ kkt @ sp.diags(d)).tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
              options={"SymmetricMode": True})
    y = d * lu.solve(d * rhs)
    for _ in range(REFINEMENT_STEPS):
        y = y + d * lu.solve(d * (rhs - kkt @ y))
    return y[:nf], free, A


def _free_design(problem, extra_columns=None) -> tuple[sp.csr_matrix, np.ndarray]:
    """The design matrix over the unknowns not held at zero, and which those are (every star
    parameter, the attitude coefficients with data), with ``extra_columns`` appended."""
    n = problem.n_stars
    free = np.concatenate([np.ones(5 * n, bool), problem.free.ravel()])
    A = sparse_design(*problem.design(), n, problem.n_coef)[:, free]
    if extra_columns is not None:
        A = sp.hstack([A, sp.csr_matrix(np.asarray(extra_columns, dtype=float))]).tocsr()
    return A, free


def _frame_rows(problem, nf: int) -> tuple[np.ndarray, sp.dia_matrix]:
    """The six frame constraint rows ``C`` (6, nf) over the free unknowns and the diagonal
    ``W`` whose inverse weights them: the penalty ``F = C' W^-1 C`` of the solver."""
    n = problem.n_stars
    K, g = problem.K, problem.frame_weights
    C = np.zeros((6, nf))
    for c in range(3):  # the six constraint rows (a loop over the 3 axes only)
        C[c, 0:5 * n:5], C[c, 1:5 * n:5] = g[:, 0] * K[:, 0, c], g[:, 0] * K[:, 1, c]
        C[3 + c, 3:5 * n:5], C[3 + c, 4:5 * n:5] = g[:, 1] * K[:, 0, c], g[:, 1] * K[:, 1, c]
    return C, sp.diags(np.r_[np.full(3, 1 / problem.w_pos), np.full(3, 1 / problem.w_pm)])


def normal_norm(problem, dx, extra_columns=None) -> float:
    """``sqrt(dx' (N + F) dx)`` for a vector ``dx`` of the free unknowns (order of
    :func:`solve_direct`'s ``x``, with ``extra_columns`` as there): the norm in which the
    solver's energy criterion measures the error, from the design matrix, prior and
    constraint rows (``N`` never formed)."""
    n = problem.n_stars
    A, _ = _free_design(problem, extra_columns)
    dx = np.asarray(dx, dtype=float)
    C, W = _frame_rows(problem, dx.size)
    c = C @ dx
    return float(np.sqrt(np.sum((A @ dx) ** 2) + np.sum(problem.prior.ravel() * dx[:5 * n] ** 2)
                         + c @ (c / W.diagonal())))

