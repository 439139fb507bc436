"""Batched solution of many small symmetric positive-definite systems.

Every star has its own 5 x 5 (or 2 x 2) normal matrix. LAPACK called once per matrix
(``numpy.linalg.solve`` on an ``(n, 5, 5)`` stack) spends most of its time in per-call
overhead, so this module runs the Cholesky factorisation "across" the stack instead:
the factorisation of a p x p matrix is unrolled over its p(p+1)/2 elements, and every
arithmetic step is one in-place numpy operation on a vector holding that element for a
block of stars (structure of arrays). The blocks are small enough to stay in the CPU
cache; the Python loop runs over blocks and matrix elements, never over stars.

Notes
-----
Singularity test. The j-th Cholesky pivot ``d_j`` (squared diagonal element of the
factor) divided by ``N_jj`` is the pivot of the unit-diagonal matrix
``S = D^-1/2 N D^-1/2`` and lies in ``(0, 1]``; exact rank deficiency shows up as a
ratio at the rounding level, ``~ p * eps ~ 1e-15``. A ratio at or below
:data:`PIVOT_TOLERANCE` marks the matrix as numerically singular. The test is thus
independent of the units of the parameters (mas versus mas/yr), while the
factorisation itself needs no explicit scaling (Cholesky is backward stable; the
accuracy of the result is governed by the condition number of ``S``, van der Sluis
1969, Numer. Math. 14, 14).

Condition number. With ``with_condition=True`` :func:`spd_solve` also returns
``kappa_1(S) = ||S||_1 ||S^-1||_1``, the 1-norm condition number of the unit-diagonal
matrix. It is exact (not an estimate) because the inverse is computed anyway, and for
p x p matrices it lies within a factor p of the 2-norm condition number (Golub & Van
Loan, Matrix Computations, 4th ed., Sect. 2.3.2).
"""

from __future__ import annotations

import numpy as np

__all__ = ["PIVOT_TOLERANCE", "BLOCK_SIZE", "spd_solve"]

#: Smallest accepted ratio of a Cholesky pivot to the matching diagonal element of the
#: matrix (dimensionless). About 100 x (p * machine epsilon) for p = 5: above the
#: rounding noise of an exactly singular matrix, far below the pivots of any matrix
#: whose scaled condition number is below 1e12.
PIVOT_TOLERANCE = 1e-13

#: Stars per block: 25 vectors of 4096 doubles (800 kB) stay in the L2/L3 caches.
BLOCK_SIZE = 4096


def spd_solve(N, b, *, add_diagonal=None, with_condition: bool = False):
    """Solve ``(N + diag(a)) x = b`` and invert ``N + diag(a)`` for a stack of matrices.

    Parameters
    ----------
    N : array_like, shape (n, p, p)
        Symmetric matrices; only the lower triangle is read.
    b : array_like, shape (n, p)
        Right-hand sides.
    add_diagonal : array_like, shape (p,) or (n, p), optional, keyword-only
        Added to the diagonal of every matrix before solving (a prior normal matrix,
        Eqs. 11 and 18), without copying ``N``.
    with_condition : bool, keyword-only
        Also compute the 1-norm condition number of the scaled matrices.

    Returns
    -------
    x : ndarray, shape (n, p)
        Solutions.
    cov : ndarray, shape (n, p, p)
        Inverses (symmetric).
    ok : ndarray of bool, shape (n,)
        False where the matrix is not numerically positive definite: a non-finite
        element, a non-positive diagonal element, or a pivot ratio at or below
        :data:`PIVOT_TOLERANCE` (module notes). Rows with ``ok == False`` hold NaN.
    condition : ndarray, shape (n,), or None
        ``kappa_1`` of the unit-diagonal matrix (module notes), ``inf`` where ``ok`` is
        False; None unless ``with_condition``.
    """
    N = np.asarray(N, dtype=float)
    b = np.asarray(b, dtype=float)
    if N.ndim != 3 or N.shape[1] != N.shape[2]:
        raise ValueError(f"N must have shape (n, p, p), got {N.shape}")
    n, p, _ = N.shape
    if b.shape != (n, p):
        raise ValueError(f"b must have shape {(n, p)}, got {b.shape}")
    add_t = None
    if add_diagonal is not None:
        add_diagonal = np.asarray(add_diagonal, dtype=float)
        if add_diagonal.shape == (p,):
            add_diagonal = np.broadcast_to(add_diagonal, (n, p))
        elif add_diagonal.shape != (n, p):
            raise ValueError(f"add_diagonal must have shape {(p,)} or {(n, p)}, got {add_diagonal.shape}")
        add_t = np.ascontiguousarray(add_diagonal.T)  # (p, n); zero rows are skipped below
        add_rows = [i for i in range(p) if np.any(add_t[i] != 0.0)]
    # Star-last output buffers: element (i, j) of every matrix is one contiguous vector.
    x_buf = np.empty((p, n))
    cov_buf = np.empty((p, p, n))
    ok = np.empty(n, dtype=bool)
    condition = np.empty(n) if with_condition else None
    for start in range(0, n, BLOCK_SIZE):
        sl = slice(start, min(start + BLOCK_SIZE, n))
        W = cov_buf[:, :, sl]
        W[...] = np.moveaxis(N[sl], 0, -1)
        add = None if add_t is None else [(i, add_t[i, sl]) for i in add_rows]
        B = x_buf[:, sl]
        B[...] = b[sl].T
        # Non-finite or singular input is flagged through ok; silence its arithmetic.
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            ok[sl], cond = _solve_block(W, B, add, with_condition)
        if condition is not None:
            condition[sl] = cond
    x = x_buf.T
    cov = np.moveaxis(cov_buf, -1, 0)
    if not ok.all():
        bad = ~ok
        x[bad] = np.nan
        cov[bad] = np.nan
        if condition is not None:
            condition[bad] = np.inf
    return x, cov, ok, condition


def _solve_block(W, B, add, with_condition):
    """Factorise, solve and invert in place: W (p, p, m) becomes the inverse, B the solution.

    ``add`` is None or a list of ``(i, vector)`` pairs added to the diagonal element i.
    Returns ``(ok, condition or None)`` for the block.
    """
    p, _, m = W.shape
    if add is not None:
        for i, a in add:
            W[i, i] += a
    tmp = np.empty(m)
    diag = np.stack([W[i, i] for i in range(p)])  # (p, m) copy of the diagonal
    ok = (diag > 0.0).all(axis=0)  # False for NaN too
    if with_condition:
        root = np.sqrt(np.where(diag > 0.0, diag, np.nan))
        norm_s = _max_abs_column_sum(W, root, p, tmp, inverse_scale=True)
    threshold = diag * PIVOT_TOLERANCE

    # Cholesky N = L L^T in place (lower triangle); rinv[j] = 1 / L_jj.
    rinv = np.empty((p, m))
    for j in range(p):
        Wjj = W[j, j]
        for k in range(j):
            np.multiply(W[j, k], W[j, k], out=tmp)
            Wjj -= tmp
        small = ~(Wjj > threshold[j])
        if small.any():  # not positive definite: carry on with a dummy pivot, NaN later
            ok &= ~small
            Wjj[small] = 1.0
        np.sqrt(Wjj, out=Wjj)
        np.divide(1.0, Wjj, out=rinv[j])
        for i in range(j + 1, p):
            Wij = W[i, j]
            for k in range(j):
                np.multiply(W[i, k], W[j, k], out=tmp)
                Wij -= tmp
            Wij *= rinv[j]

    # Forward then back substitution, L y = b and L^T x = y, in place in B.
    for i in range(p):
        for k in range(i):
            np.multiply(W[i, k], B[k], out=tmp)
            B[i] -= tmp
        B[i] *= rinv[i]
    for i in range(p - 1, -1, -1):
        for k in range(i + 1, p):
            np.multiply(W[k, i], B[k], out=tmp)
            B[i] -= tmp
        B[i] *= rinv[i]

    # M = L^-1 in place, column by column (M_jj = 1 / L_jj).
    for j in range(p):
        W[j, j] = rinv[j]
        for i in range(j + 1, p):
            Wij = W[i, j]
            Wij *= W[j, j]  # L_ij M_jj
            for k in range(j + 1, i):
                np.multiply(W[i, k], W[k, j], out=tmp)
                Wij += tmp
            Wij *= rinv[i]
            np.negative(Wij, out=Wij)

    # N^-1 = M^T M in place: (i, j) <- sum_{k >= i} M_ki M_kj, with the diagonal
    # element of row i updated last because the others still need M_ii.
    for i in range(p):
        for j in list(range(i)) + [i]:
            Wij = W[i, j]
            Wij *= W[i, i]
            for k in range(i + 1, p):
                np.multiply(W[k, i], W[k, j], out=tmp)
                Wij += tmp
        for j in range(i):
            W[j, i] = W[i, j]

    # Non-finite input propagates into the solution or the diagonal of the inverse.
    np.add(B.sum(axis=0), sum(W[i, i] for i in range(p)), out=tmp)
    ok &= np.isfinite(tmp)
    cond = None
    if with_condition:
        cond = norm_s * _max_abs_column_sum(W, root, p, tmp, inverse_scale=False)
    return ok, cond


def _max_abs_column_sum(W, root, p, tmp, *, inverse_scale):
    """1-norm of the unit-diagonal version of the symmetric matrices in W.

    ``S_ij = W_ij / (root_i root_j)`` for the matrix itself (``inverse_scale=True``),
    ``W_ij * root_i * root_j`` for its inverse. Reads the lower triangle only.
    """
    best = None
    for j in range(p):
        col = np.zeros_like(tmp)
        for i in range(p):
            np.abs(W[i, j] if i >= j else W[j, i], out=tmp)
            if inverse_scale:
                tmp /= root[i]
                tmp /= root[j]
            else:
                tmp *= root[i]
                tmp *= root[j]
            col += tmp
        best = col if best is None else np.maximum(best, col, out=best)
    return best
