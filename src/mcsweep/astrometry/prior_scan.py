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

The 3 x 3 eigen-decompositions use cyclic Jacobi rotations, compiled and vectorised
across stars (:mod:`mcsweep.astrometry.scan_kernel`; Golub & Van Loan, Sect. 8.5):
Jacobi is accurate to the rounding level for every eigenvalue relative to the matrix
norm. A rotation is skipped for a star whose off-diagonal element is already negligible
(below ``scan_kernel.JACOBI_NEGLIGIBLE`` times its two diagonal elements), a per-star
test, so every star's arithmetic is independent of the others (results do not depend on
batching); the sweeps stop once every star of a block has converged.

For the pencil-beam search only the inside/outside test of every star and prior is
needed on the whole grid (:meth:`PriorScan.inside_flags`): the five quantities of the
test (error and covariance, above) are ``y_j + sum_k X_jk w_k`` with per-star
``X`` built once, about 40 operations per star and prior in one compiled pass per star
(:mod:`mcsweep.astrometry.scan_kernel`), followed by the rule of
:func:`mcsweep.astrometry.confidence.inside_components`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .confidence import chi2_threshold
from .linalg import PIVOT_TOLERANCE
from .solve import DEFAULT_RATIO_R, check_normal, prior_diagonal

__all__ = ["MAX_KEY_PRIORS", "PriorScan", "prior_scan"]

# The compiled passes (mcsweep.astrometry.scan_kernel) are imported where they run: loading
# numba costs a process 54 MB and 0.14 s, and the sweep's parent process never runs them.

#: Most priors whose per-star flags fit the bits of one integer (:meth:`PriorScan.inside_counts`).
MAX_KEY_PRIORS = 64



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
        ts = self._ts(priors_mas)
        m, n = len(ts), self.n
        inside = np.zeros((m, n), dtype=bool)
        valid = np.zeros((m, n), dtype=bool)
        if m and n:
            from .scan_kernel import inside_flags_grid

            inside_flags_grid(*self._kernel_arrays, ts, chi2_threshold(P, 2), inside, valid)
        return inside, valid

    def inside_counts(self, priors_mas, P, *, keys: bool = False):
        """The counts of :meth:`inside_flags` per prior, without the per-star flags.

        Returns
        -------
        n_inside, n_valid : ndarray of int64, shape (n_priors,)
        key_inside, key_valid : ndarray of uint64, shape (n,), or None
            With ``keys`` (at most 64 priors): each star's ``inside`` and ``valid`` flags
            over the priors as the bits of one integer (bit i: prior i).
        """
        ts = self._ts(priors_mas)
        m, n = len(ts), self.n
        if keys and m > MAX_KEY_PRIORS:
            raise ValueError(f"{m} priors: per-star keys hold at most {MAX_KEY_PRIORS}")
        n_in = np.zeros(m, dtype=np.int64)
        n_val = np.zeros(m, dtype=np.int64)
        k_in = np.zeros(n if keys else 0, dtype=np.uint64)
        k_val = np.zeros(n if keys else 0, dtype=np.uint64)
        if m and n:
            from .scan_kernel import inside_counts_grid

            inside_counts_grid(*self._kernel_arrays, ts, chi2_threshold(P, 2), n_in, n_val, k_in, k_val)
        return n_in, n_val, (k_in, k_val) if keys else None

    def position_statistics(self, priors_mas, P) -> tuple[np.ndarray, np.ndarray]:
        """Each star's actual position error and the semi-major axis of its P confidence
        ellipse, mas, at every prior of ``priors_mas``.

        ``np.hypot`` of :meth:`position`'s estimate (the true offset is zero, Sect. 3.2) and
        the first value of :func:`mcsweep.astrometry.confidence.ellipse_semi_axes` of its
        covariance, bit for bit, in one compiled pass.

        Returns
        -------
        error, semi_major : ndarray, shape (n_priors, n)
            NaN where the star has no solution (``ok`` False, or the rule of :meth:`_bad`).
        """
        ts = self._ts(priors_mas)
        err = np.empty((len(ts), self.n))
        semi = np.empty((len(ts), self.n))
        if len(ts) and self.n:
            from .scan_kernel import position_statistics_grid

            position_statistics_grid(*self._kernel_arrays, ts, chi2_threshold(P, 2), err, semi)
        return err, semi

    def _ts(self, priors_mas) -> np.ndarray:
        """The prior term t of Eq. 18 for each prior width, contiguous (the kernels' input)."""
        priors = np.atleast_1d(np.asarray(priors_mas, float))
        if priors.ndim > 1 or not np.all(priors > 0):
            prior_diagonal(priors, self.ratio_R)  # its one-line refusal
        # prior_diagonal's t (1 / sigma^2, the same operations), without its checks and stacking:
        # a cell asks for the grid's and sigma_F90's t of every case (1 ms of a 44 ms cell)
        return 1.0 / priors**2

    @cached_property
    def _kernel_arrays(self) -> tuple:
        """The scan's arrays as the compiled passes take them, and ``worst``: the rule of
        :meth:`_bad` as one comparison per star and prior (no reliable solution where
        min(lam) + t <= 0, or where the star is not ok: then -inf). Made once per scan: a
        cell's case asks for them at the grid and again at sigma_F90."""
        worst = np.where(self.ok, np.min(self.lam, axis=0), -np.inf)
        return tuple(np.ascontiguousarray(a) for a in (self.x0, self.ainv, self.g, self.c, self.lam)) + (worst,)


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
    from .scan_kernel import reduce_normals

    N0, b0 = check_normal(N0, b0)
    prior_diagonal(1.0, ratio_R)  # validates ratio_R
    r_ = float(ratio_R)
    n = N0.shape[0]
    out = dict(x0=np.empty((2, n)), ainv=np.empty((3, n)), g=np.empty((2, 3, n)), c=np.empty((3, n)),
               lam=np.empty((3, n)), ok=np.empty(n, dtype=bool))
    reduce_normals(np.moveaxis(N0, 0, -1), b0.T, r_, PIVOT_TOLERANCE, out["x0"], out["ainv"], out["g"], out["c"],
                   out["lam"], out["ok"])
    return PriorScan(ratio_R=r_, **out)
