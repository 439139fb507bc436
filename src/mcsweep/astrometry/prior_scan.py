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
(Golub & Van Loan, Sect. 8.5): Jacobi is accurate to the rounding level for every
eigenvalue relative to the matrix norm. A rotation is skipped for a star whose
off-diagonal element is already negligible (below ``JACOBI_NEGLIGIBLE`` times its two
diagonal elements), a per-star test, so every star's arithmetic is independent of the
others (results do not depend on batching); the sweeps stop once every star has
converged.

For the pencil-beam search only the inside/outside test of every star and prior is
needed on the whole grid (:meth:`PriorScan.inside_flags`): the five quantities of the
test (error and covariance, above) are ``y_j + sum_k X_jk w_k`` with per-star
``X`` built once, about 40 operations per star and prior in one compiled pass per star
(:mod:`mcsweep.astrometry.scan_kernel`), followed by the rule of
:func:`mcsweep.astrometry.confidence.inside_components`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .confidence import chi2_threshold
from .linalg import PIVOT_TOLERANCE
from .scan_kernel import inside_flags_grid
from .solve import DEFAULT_RATIO_R, check_normal, prior_diagonal

__all__ = ["JACOBI_SWEEPS", "JACOBI_NEGLIGIBLE", "REDUCE_BLOCK", "PriorScan", "prior_scan"]

#: Most cyclic Jacobi sweeps for a 3 x 3 symmetric matrix. Convergence is quadratic
#: after the first sweep (Golub & Van Loan, Sect. 8.5.4); 3 x 3 matrices reach the
#: rounding level in 4-5 sweeps.
JACOBI_SWEEPS = 8
#: A rotation is skipped where ``|a_pq| <= JACOBI_NEGLIGIBLE * (|a_pp| + |a_qq|)``:
#: two orders of magnitude below the rounding of the diagonal elements, so skipping it
#: changes no eigenvalue or eigenvector beyond rounding.
JACOBI_NEGLIGIBLE = 1e-18
#: Stars per block of the reduction (:func:`prior_scan`): its temporaries (vectors of
#: REDUCE_BLOCK doubles) stay in cache.
REDUCE_BLOCK = 4096


def _jacobi3(t):
    """Eigen-decomposition of symmetric 3 x 3 matrices ``t`` (3, 3, n), star-last.

    Returns ``lam (3, n)`` and ``v (3, 3, n)`` with ``T = V diag(lam) V'`` (columns of
    ``v[:, i]`` are the eigenvectors).
    """
    a = t.copy()
    v = np.zeros_like(a)
    for i in range(3):
        v[i, i] = 1.0
    # theta overflows to inf for a negligible off-diagonal element: the rotation is then
    # the identity (t = 0), as it should be.
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for _ in range(JACOBI_SWEEPS):
            active = False
            for p, q in ((0, 1), (0, 2), (1, 2)):
                apq = a[p, q]
                nz = np.abs(apq) > JACOBI_NEGLIGIBLE * (np.abs(a[p, p]) + np.abs(a[q, q]))
                if not nz.any():
                    continue  # identity rotations for every star
                active = True
                # Numerical Recipes Sect. 11.1 rotation: t = sgn(theta)/(|theta| + sqrt(theta^2+1)).
                theta = (a[q, q] - a[p, p]) / (2.0 * np.where(nz, apq, 1.0))
                tr = np.copysign(1.0, theta) / (np.abs(theta) + np.hypot(theta, 1.0))
                tr[~nz] = 0.0
                c = 1.0 / np.sqrt(tr * tr + 1.0)
                s = tr * c
                tapq = tr * apq
                a[p, p] -= tapq
                a[q, q] += tapq
                a[p, q] = a[q, p] = np.where(nz, 0.0, apq)
                r = 3 - p - q
                arp = c * a[r, p] - s * a[r, q]
                arq = s * a[r, p] + c * a[r, q]
                a[r, p] = a[p, r] = arp
                a[r, q] = a[q, r] = arq
                vp = c * v[:, p] - s * v[:, q]
                vq = s * v[:, p] + c * v[:, q]
                v[:, p], v[:, q] = vp, vq
            if not active:
                break
    return np.stack([a[0, 0], a[1, 1], a[2, 2]]), v


@dataclass(frozen=True)
class PriorScan:
    """Per-star reduction of ``(N0, b0)`` that evaluates any prior of Eq. 18 cheaply.

    Arrays are star-last. Build with :func:`prior_scan`; evaluate with
    :meth:`position` (one prior, position and covariance) or :meth:`inside_flags`
    (many priors, the confidence-ellipse test only).
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

    def _t(self, sigma_plx_prior_mas) -> float:
        return float(prior_diagonal(float(sigma_plx_prior_mas), self.ratio_R)[2])

    def position(self, sigma_plx_prior_mas: float) -> tuple[np.ndarray, np.ndarray]:
        """Position estimate (n, 2) and covariance (n, 2, 2) for one prior, mas and mas^2.

        Equal to ``solve_with_prior(N0, b0, sigma, ratio_R).x[:, :2]`` and ``.cov[:, :2, :2]``
        to rounding (module notes); NaN where ``ok`` is False.
        """
        t = self._t(sigma_plx_prior_mas)
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
        bad = self._bad(t)
        if bad.any():
            dpos[bad] = np.nan
            cov[bad] = np.nan
        return dpos, cov

    def _bad(self, t: float, sl=slice(None)) -> np.ndarray:
        # lam + t <= 0 only if rounding made a singular S slightly indefinite and the
        # prior is weaker than that rounding: no reliable solution, as in spd_solve.
        lam = self.lam[:, sl]
        return ~self.ok[sl] | ~((lam[0] + t > 0.0) & (lam[1] + t > 0.0) & (lam[2] + t > 0.0))

    def inside_flags(self, priors_mas, P) -> tuple[np.ndarray, np.ndarray]:
        """Whether each star's true position (the origin) lies inside its P ellipse, per prior.

        The test of :func:`mcsweep.astrometry.confidence.inside_components` on the
        solution of :meth:`position` (the position error is the solved position: the
        true offset is zero, Sect. 3.2), for every prior of ``priors_mas`` without
        forming the solutions (module notes).

        Returns
        -------
        inside, valid : ndarray of bool, shape (n_priors, n)
            ``valid`` False where the star has no confidence region (``ok`` False, or
            the NaN rule); ``inside`` implies ``valid``.
        """
        priors = np.atleast_1d(np.asarray(priors_mas, float))
        ts = prior_diagonal(priors, self.ratio_R)[:, 2] if priors.size else np.zeros(0)
        m, n = len(ts), self.n
        inside = np.zeros((m, n), dtype=bool)
        valid = np.zeros((m, n), dtype=bool)
        # The rule of _bad as one comparison per star and prior: no reliable solution
        # where min(lam) + t <= 0 or the star is not ok (then -inf).
        worst = np.where(self.ok, np.min(self.lam, axis=0), -np.inf) if n else np.zeros(0)
        if m and n:
            inside_flags_grid(np.ascontiguousarray(self.x0), np.ascontiguousarray(self.ainv),
                              np.ascontiguousarray(self.g), np.ascontiguousarray(self.c),
                              np.ascontiguousarray(self.lam), worst, np.ascontiguousarray(ts, dtype=float),
                              chi2_threshold(P, 2), inside, valid)
        return inside, valid


def prior_scan(N0, b0, ratio_R: float = DEFAULT_RATIO_R) -> PriorScan:
    """Reduce normal equations once for evaluation with many priors (module notes).

    Parameters
    ----------
    N0 : array_like, shape (n, 5, 5)
        Normal matrices of Eq. 2 (parameter order of :mod:`mcsweep.astrometry.design`).
        A star-last memory layout (a ``(5, 5, n)`` array seen through ``np.moveaxis``)
        is the fastest.
    b0 : array_like, shape (n, 5)
    ratio_R : float
        ``sigma_mu,p / sigma_plx,p`` in 1/yr (Sect. 3.1, Eq. 18).

    Returns
    -------
    PriorScan
    """
    N0, b0 = check_normal(N0, b0)
    prior_diagonal(1.0, ratio_R)  # validates ratio_R
    r_ = float(ratio_R)
    n = N0.shape[0]
    N = np.moveaxis(N0, 0, -1)  # (5, 5, n) views
    b = b0.T
    out = dict(x0=np.empty((2, n)), ainv=np.empty((3, n)), g=np.empty((2, 3, n)), c=np.empty((3, n)),
               lam=np.empty((3, n)), ok=np.empty(n, dtype=bool))
    # Blocks of stars: every temporary stays small (cache-resident, no mmap per array);
    # each star's arithmetic is the same in any block (bit-identical results).
    for lo in range(0, n, REDUCE_BLOCK):
        sl = slice(lo, min(n, lo + REDUCE_BLOCK))
        for key, value in _reduce(N[:, :, sl], b[:, sl], r_).items():
            out[key][..., sl] = value
    return PriorScan(ratio_R=r_, **out)


def _reduce(N, b, r_: float) -> dict:
    """The reduction of :func:`prior_scan` for star-last ``N (5, 5, n)``, ``b (5, n)``."""
    a11, a12, a22 = N[0, 0], 0.5 * (N[0, 1] + N[1, 0]), N[1, 1]
    det = a11 * a22 - a12 * a12
    # Same singularity test as the Cholesky solver: the second pivot det / a11 relative
    # to a22 (mcsweep.astrometry.linalg notes).
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = (a11 > 0) & (a22 > 0) & (det > PIVOT_TOLERANCE * a11 * a22) & np.isfinite(det)
        det_safe = np.where(ok, det, 1.0)
        ainv = np.stack([a22 / det_safe, -a12 / det_safe, a11 / det_safe])
    ai = ((ainv[0], ainv[1]), (ainv[1], ainv[2]))
    B = [[np.ascontiguousarray(N[i, 2 + k]) for k in range(3)] for i in range(2)]
    bp = [np.ascontiguousarray(b[i]) for i in range(2)]
    # Explicit 2 x 3 products (faster than einsum on star-last vectors).
    aib = [[ai[i][0] * B[0][k] + ai[i][1] * B[1][k] for k in range(3)] for i in range(2)]
    x0 = np.stack([ai[i][0] * bp[0] + ai[i][1] * bp[1] for i in range(2)])
    scale = (1.0, r_, r_)
    # T = W3^-1/2 S W3^-1/2 with W3^-1/2 = diag(1, R, R), S = C - B' A^-1 B symmetrised.
    T = np.empty((3, 3, N.shape[-1]))
    for j in range(3):
        for k in range(j, 3):
            sjk = N[2 + j, 2 + k] - (B[0][j] * aib[0][k] + B[1][j] * aib[1][k])
            skj = N[2 + k, 2 + j] - (B[0][k] * aib[0][j] + B[1][k] * aib[1][j])
            v = 0.5 * (sjk + skj) * (scale[j] * scale[k])
            T[j, k] = v
            T[k, j] = v
    r = [b[2 + k] - (B[0][k] * x0[0] + B[1][k] * x0[1]) for k in range(3)]
    T[:, :, ~ok] = 0.0  # keep NaN of singular stars out of the rotations
    lam, V = _jacobi3(T)
    U = V * np.asarray(scale)[:, None, None]
    g = np.empty((2, 3, N.shape[-1]))
    for i in range(2):
        for k in range(3):
            g[i, k] = aib[i][0] * U[0, k] + aib[i][1] * U[1, k] + aib[i][2] * U[2, k]
    c = np.stack([U[0, k] * r[0] + U[1, k] * r[1] + U[2, k] * r[2] for k in range(3)])
    return dict(x0=x0, ainv=ainv, g=g, c=c, lam=lam, ok=ok)
