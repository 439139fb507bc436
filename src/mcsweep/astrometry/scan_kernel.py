"""The prior scan's inside test over the whole prior grid, compiled: one pass per star.

:meth:`mcsweep.astrometry.prior_scan.PriorScan.inside_flags` evaluates, for every star and
every prior t of the grid, the five quantities ``y_j = base_j + sum_k X_jk w_k`` (position
error and covariance, ``w_k = 1 / (lam_k + t)``) and the ellipse test of
:func:`mcsweep.astrometry.confidence.inside_components`. As numpy vector operations that is
some 25 passes over star-length arrays per prior; here each star's 20 numbers stay in
registers while its whole grid is tested.

Same numbers as the numpy path, bit for bit: every expression is evaluated in the order
and with the roundings the numpy code uses (``y = X0 w0 + base``, then ``+ X1 w1``, then
``+ X2 w2``; ``Q det = ((cdd dx - 2 (cad dy)) dx) + (caa dy) dy``), and numba compiles
without ``fastmath``, so LLVM neither reassociates nor contracts into fused multiply-adds
(tests/astrometry/test_prior_scan.py compares the flags of both paths).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["inside_flags_grid"]

_jit = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False)


@_jit
def inside_flags_grid(x0, ainv, g, c, lam, worst, ts, k_threshold, inside, valid):
    """Fill ``inside`` and ``valid`` (m, n) for the priors ``ts`` (m,) (prior-scan arrays, star-last).

    ``worst`` (n,): the smallest eigenvalue, -inf for a star whose position block is
    singular: no solution where ``worst + t <= 0`` (the rule of ``PriorScan._bad``).
    """
    m = ts.shape[0]
    n = worst.shape[0]
    for s in range(n):
        b0, b1, b2, b3, b4 = x0[0, s], x0[1, s], ainv[0, s], ainv[1, s], ainv[2, s]
        l0, l1, l2 = lam[0, s], lam[1, s], lam[2, s]
        # X[k] = (-(g0 c_k), -(g1 c_k), g0 g0, g0 g1, g1 g1) as in PriorScan.inside_flags.
        X = np.empty((3, 5))
        for k in range(3):
            g0 = g[0, k, s]
            g1 = g[1, k, s]
            X[k, 0] = -(g0 * c[k, s])
            X[k, 1] = -(g1 * c[k, s])
            X[k, 2] = g0 * g0
            X[k, 3] = g0 * g1
            X[k, 4] = g1 * g1
        wst = worst[s]
        for i in range(m):
            t = ts[i]
            w0 = 1.0 / (l0 + t)
            w1 = 1.0 / (l1 + t)
            w2 = 1.0 / (l2 + t)
            dx = ((X[0, 0] * w0 + b0) + X[1, 0] * w1) + X[2, 0] * w2
            dy = ((X[0, 1] * w0 + b1) + X[1, 1] * w1) + X[2, 1] * w2
            caa = ((X[0, 2] * w0 + b2) + X[1, 2] * w1) + X[2, 2] * w2
            cad = ((X[0, 3] * w0 + b3) + X[1, 3] * w1) + X[2, 3] * w2
            cdd = ((X[0, 4] * w0 + b4) + X[1, 4] * w1) + X[2, 4] * w2
            t1 = (cdd * dx - (cad * dy) * 2.0) * dx
            t1 = t1 + (caa * dy) * dy
            det = caa * cdd - cad * cad
            q = t1 / det
            ok = (det > 0.0) and (caa > 0.0) and np.isfinite(q) and (wst + t > 0.0)
            valid[i, s] = ok
            inside[i, s] = ok and (q < k_threshold)

