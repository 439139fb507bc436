"""Position solutions of many stars for a whole grid of priors at once (Eqs. 11-13, 18).

For one star and one observation case the normal matrix ``N0`` and right-hand side
``b0`` are fixed; the paper's prior (Eq. 18) only adds ``t W`` to the diagonal, with
``t = sigma_plx^-2`` and ``W = diag(0, 0, 1, R^-2, R^-2)``. The pencil-beam search
(Sect. 3.3) needs the position estimate and its 2 x 2 covariance for ~40 values of
``t``; solving a 5 x 5 system per prior repeats almost all the arithmetic.

Method. Partition ``N0`` into the position block ``A`` (2 x 2), the coupling ``B``
(2 x 3) and the parallax/proper-motion block ``C`` (3 x 3). Eliminating the position
(the first two Cholesky steps of the full solver do the same) leaves the Schur
complement ``S = C - B' A^-1 B`` and ``r = b_q - B' A^-1 b_p``. With
``W3 = diag(1, R^-2, R^-2)``, ``T = W3^-1/2 S W3^-1/2 = V diag(lam) V'`` (symmetric
eigen-decomposition, once per star) and ``U = W3^-1/2 V``,

    (S + t W3)^-1 = U diag(1 / (lam + t)) U',

so with ``G = A^-1 B U``, ``c = U' r`` and ``w = 1 / (lam + t)``

    position      = A^-1 b_p - G (w * c),
    position cov  = A^-1 + G diag(w) G'          (block inverse, e.g. Golub & Van Loan,
                                                  Matrix Computations, Sect. 3.2.11),

exact for every ``t`` and O(15) operations per star and prior. ``S`` may be singular
(one or two transits: ``N0`` has rank < 5); ``S + t W3`` is regular for every ``t > 0``,
so no step divides by a singular quantity. A singular position block ``A`` (AL data in
one scan direction only) leaves the position undetermined with any prior of Eq. 18,
as in :func:`mcsweep.astrometry.solve.solve_with_prior`: such stars get NaN.

The 3 x 3 eigen-decompositions use cyclic Jacobi rotations vectorised across stars
(Golub & Van Loan, Sect. 8.5), a fixed number of sweeps: Jacobi is accurate to the
rounding level for every eigenvalue relative to the matrix norm, and every star's
arithmetic is independent of the others (results do not depend on batching).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .linalg import PIVOT_TOLERANCE
from .solve import DEFAULT_RATIO_R, _check_normal, prior_diagonal

__all__ = ["JACOBI_SWEEPS", "PriorScan", "prior_scan"]

#: Cyclic Jacobi sweeps for a 3 x 3 symmetric matrix. Convergence is quadratic after the
#: first sweep (Golub & Van Loan, Sect. 8.5.4); 3 x 3 matrices reach the rounding level
#: in 4-5 sweeps, the extra ones cost nothing measurable and leave converged matrices
#: unchanged (rotations with a zero off-diagonal element are the identity).
JACOBI_SWEEPS = 8


def _jacobi3(t):
    """Eigen-decomposition of symmetric 3 x 3 matrices ``t`` (3, 3, n), star-last.

    Returns ``lam (3, n)`` and ``v (3, 3, n)`` with ``T = V diag(lam) V'`` (columns of
    ``v[:, i]`` are the eigenvectors).
    """
    a = t.copy()
    n = a.shape[-1]
    v = np.zeros_like(a)
    for i in range(3):
        v[i, i] = 1.0
    # theta overflows to inf for a negligible off-diagonal element: the rotation is then
    # the identity (t = 0), as it should be.
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for _ in range(JACOBI_SWEEPS):
            for p, q in ((0, 1), (0, 2), (1, 2)):
                apq = a[p, q]
                nz = apq != 0.0
                # Numerical Recipes Sect. 11.1 rotation: t = sgn(theta)/(|theta| + sqrt(theta^2+1)).
                theta = np.where(nz, (a[q, q] - a[p, p]) / (2.0 * np.where(nz, apq, 1.0)), 0.0)
                tr = np.where(nz, np.where(theta >= 0, 1.0, -1.0) / (np.abs(theta) + np.hypot(theta, 1.0)), 0.0)
                c = 1.0 / np.sqrt(tr * tr + 1.0)
                s = tr * c
                app = a[p, p] - tr * apq
                aqq = a[q, q] + tr * apq
                r = 3 - p - q
                arp = c * a[r, p] - s * a[r, q]
                arq = s * a[r, p] + c * a[r, q]
                a[p, p], a[q, q] = app, aqq
                a[p, q] = a[q, p] = np.zeros(n)
                a[r, p] = a[p, r] = arp
                a[r, q] = a[q, r] = arq
                vp = c * v[:, p] - s * v[:, q]
                vq = s * v[:, p] + c * v[:, q]
                v[:, p], v[:, q] = vp, vq
    return np.stack([a[0, 0], a[1, 1], a[2, 2]]), v


@dataclass(frozen=True)
class PriorScan:
    """Per-star reduction of ``(N0, b0)`` that evaluates any prior of Eq. 18 cheaply.

    Arrays are star-last. Build with :func:`prior_scan`; evaluate with
    :meth:`position`.
    """

    x0: np.ndarray      # (2, n) A^-1 b_p
    ainv: np.ndarray    # (3, n) A^-1 elements (aa, ad, dd)
    g: np.ndarray       # (2, 3, n) A^-1 B U
    c: np.ndarray       # (3, n) U' r
    lam: np.ndarray     # (3, n) eigenvalues of T
    ok: np.ndarray      # (n,) False where the position block is singular
    ratio_R: float

    @property
    def n(self) -> int:
        return self.ok.shape[0]

    def position(self, sigma_plx_prior_mas: float) -> tuple[np.ndarray, np.ndarray]:
        """Position estimate (n, 2) and covariance (n, 2, 2) for one prior, mas and mas^2.

        Equal to ``solve_with_prior(N0, b0, sigma, ratio_R).x[:, :2]`` and ``.cov[:, :2, :2]``
        to rounding (module notes); NaN where ``ok`` is False.
        """
        t = float(prior_diagonal(float(sigma_plx_prior_mas), self.ratio_R)[2])
        g = self.g
        # Star-last buffers returned as (n, 2) and (n, 2, 2) views: every element is a
        # contiguous vector for the consumers (mahalanobis_sq, ellipse_semi_axes).
        d = np.empty((2, self.n))
        cv = np.empty((2, 2, self.n))
        with np.errstate(invalid="ignore", divide="ignore"):
            w = 1.0 / (self.lam + t)
            wc = w * self.c
            for i in range(2):
                np.subtract(self.x0[i], g[i, 0] * wc[0] + g[i, 1] * wc[1] + g[i, 2] * wc[2], out=d[i])
            wg0 = w * g[0]
            cv[0, 0] = self.ainv[0] + (wg0[0] * g[0, 0] + wg0[1] * g[0, 1] + wg0[2] * g[0, 2])
            cv[0, 1] = self.ainv[1] + (wg0[0] * g[1, 0] + wg0[1] * g[1, 1] + wg0[2] * g[1, 2])
            cv[1, 1] = self.ainv[2] + (w[0] * g[1, 0] ** 2 + w[1] * g[1, 1] ** 2 + w[2] * g[1, 2] ** 2)
            cv[1, 0] = cv[0, 1]
        dpos, cov = d.T, np.moveaxis(cv, -1, 0)
        # lam + t <= 0 only if rounding made a singular S slightly indefinite and the
        # prior is weaker than that rounding: no reliable solution, as in spd_solve.
        bad = ~self.ok | ~np.all(self.lam + t > 0.0, axis=0)
        if bad.any():
            dpos[bad] = np.nan
            cov[bad] = np.nan
        return dpos, cov


def prior_scan(N0, b0, ratio_R: float = DEFAULT_RATIO_R) -> PriorScan:
    """Reduce normal equations once for evaluation with many priors (module notes).

    Parameters
    ----------
    N0 : array_like, shape (n, 5, 5)
        Normal matrices of Eq. 2 (parameter order of :mod:`mcsweep.astrometry.design`).
    b0 : array_like, shape (n, 5)
    ratio_R : float
        ``sigma_mu,p / sigma_plx,p`` in 1/yr (Sect. 3.1, Eq. 18).

    Returns
    -------
    PriorScan
    """
    N0, b0 = _check_normal(N0, b0)
    prior_diagonal(1.0, ratio_R)  # validates ratio_R
    r_ = float(ratio_R)
    n = N0.shape[0]
    N = np.moveaxis(N0, 0, -1)  # (5, 5, n) views
    b = b0.T
    a11, a12, a22 = N[0, 0], 0.5 * (N[0, 1] + N[1, 0]), N[1, 1]
    det = a11 * a22 - a12 * a12
    # Same singularity test as the Cholesky solver: the second pivot det / a11 relative
    # to a22 (mcsweep.astrometry.linalg notes).
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = (a11 > 0) & (a22 > 0) & (det > PIVOT_TOLERANCE * a11 * a22) & np.isfinite(det)
        det_safe = np.where(ok, det, 1.0)
        ainv = np.stack([a22 / det_safe, -a12 / det_safe, a11 / det_safe])
    ai = np.array([[ainv[0], ainv[1]], [ainv[1], ainv[2]]])  # (2, 2, n)
    B = N[:2, 2:]  # (2, 3, n)
    C = N[2:, 2:]
    aib = np.einsum("ijn,jkn->ikn", ai, B)  # A^-1 B (2, 3, n)
    x0 = np.einsum("ijn,jn->in", ai, b[:2])
    S = C - np.einsum("jin,jkn->ikn", B, aib)
    S = 0.5 * (S + S.transpose(1, 0, 2))
    r = b[2:] - np.einsum("jin,jn->in", B, x0)
    # T = W3^-1/2 S W3^-1/2 with W3^-1/2 = diag(1, R, R).
    scale = np.array([1.0, r_, r_])
    T = S * scale[:, None, None] * scale[None, :, None]
    T[:, :, ~ok] = 0.0  # keep NaN of singular stars out of the rotations
    lam, V = _jacobi3(T)
    U = V * scale[:, None, None]
    g = np.einsum("ijn,jkn->ikn", aib, U)
    c = np.einsum("jin,jn->in", U, r)
    return PriorScan(x0=x0, ainv=ainv, g=g, c=c, lam=lam, ok=ok, ratio_R=r_)
