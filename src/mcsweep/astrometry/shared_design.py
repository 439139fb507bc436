"""Normal equations of many stars observed with one design, kept in factored form.

All stars of a pencil-beam cell are observed with the transits of the beam centre
(paper Sect. 3.2), so their design matrices differ only by the per-star measurement
uncertainties: ``A_i = diag(1/sigma_i) U`` with ``U`` the design at unit uncertainty
(AL rows, then AC rows). Hence (Eqs. 2-3)

    N_i = sum_blk U_blk' U_blk / sigma_blk,i^2,
    b_i = N_i x_i + n_i,   n_i = sum_blk U_blk' e_blk,i / sigma_blk,i ~ Gaussian(0, N_i),

with ``e`` the standard normal measurement noise. The normal equations are all a
least-squares solution with any prior uses (they are sufficient statistics of the linear
Gaussian model), so a star's noise is drawn as a Gaussian vector of covariance ``N_i``
directly, with five standard normals per star instead of one per measurement. Partition
``n = (n_p, n_q)`` like ``N`` into the position block ``A`` (2 x 2), the coupling ``B`` and the
rest ``C``; with ``z`` five standard normals

    n_p = L_A z[:2],                           L_A L_A' = A (Cholesky),
    n_q = B' A^-1 n_p + L sqrt(D) z[2:],       L D L' = S = C - B' A^-1 B (pivoted),

so ``n_p`` has covariance ``A``, and ``n_q - B' A^-1 n_p`` (what the prior scan's reduction
keeps of ``b_q``, :mod:`mcsweep.astrometry.prior_scan`) covariance ``S``, independent of
``n_p``: ``n`` has covariance ``N``, exactly the distribution of the per-measurement draw.
A singular ``S`` (one or two transits) has zero pivots in its null space and no noise there
(the LDL' takes the largest remaining diagonal element first, and a pivot at the rounding of
S's formation counts as zero: :data:`mcsweep.astrometry.scan_kernel.NULL_PIVOT`). The factors
depend on ``N`` alone, so a star's noise is the same whatever prior ratio R the scan then
uses. Unlike a draw per measurement, the construction goes through ``A^-1``: its rounding is
eps cond(A) of N in the worst direction (with AC rows A is well conditioned: a transit's AL
and AC position derivatives are orthogonal; AL data alone from nearly one scan direction
make it ill-conditioned, and then the rounding is larger).

:class:`SharedDesignNormals` holds the factors, the weights, the truths and the normals;
:meth:`~SharedDesignNormals.prior_scan` reduces every star for the prior scan in one
compiled pass that forms each star's normal equations on the way
(:func:`mcsweep.astrometry.scan_kernel.reduce_shared_design`), and
:meth:`~SharedDesignNormals.matrices` gives them explicitly, with the same noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .linalg import PIVOT_TOLERANCE
from .prior_scan import PriorScan
from .solve import prior_diagonal

__all__ = ["SharedDesignNormals"]


@dataclass(frozen=True)
class SharedDesignNormals:
    """The normal equations of ``n`` stars observed with one design (module notes)."""

    #: (n_blk, r, 5): each block's triangular factor R at unit uncertainty (AL, then AC if
    #: used; ``R' R = U' U``, r = min(k, 5)).
    unit: np.ndarray
    #: (n_blk, n): each star's 1 / sigma per block [1/mas].
    weight: np.ndarray
    #: (3, n): true parallax [mas] and proper motion [mas/yr]; the true position offsets are zero.
    truth: np.ndarray
    #: (5, n): standard normals, the noise of the reduced normal equations (module notes).
    noise: np.ndarray

    @classmethod
    def simulate(cls, unit_design, weights, truth, rng: np.random.Generator) -> "SharedDesignNormals":
        """Draw every star's measurement noise for the design ``unit_design (m, 5)`` at unit
        uncertainty, its ``len(weights)`` blocks of rows stacked (AL rows, then AC rows: one or two);
        ``weights``: a sequence of (n,) arrays of 1 / sigma, ``truth (3, n)``. The noise is one
        ``(5, n)`` array of standard normals from ``rng`` (module notes)."""
        a = np.asarray(unit_design, dtype=float)
        w = np.ascontiguousarray(np.stack([np.asarray(x, float) for x in weights]))
        x = np.ascontiguousarray(truth, dtype=float)
        n_blk, n = w.shape
        if n_blk not in (1, 2):
            raise ValueError(f"{n_blk} blocks of weights; expected 1 (AL) or 2 (AL, then AC)")
        if a.ndim != 2 or a.shape[1] != 5 or a.shape[0] % n_blk or x.shape != (3, n):
            raise ValueError(f"unit_design {a.shape}, weights {w.shape}, truth {x.shape}: expected (m, 5) with m a "
                             "multiple of the number of weight blocks, and truth (3, n)")
        k = a.shape[0] // n_blk
        r = np.ascontiguousarray(np.stack([np.linalg.qr(blk, mode="r") for blk in a.reshape(n_blk, k, 5)]))
        return cls(unit=r, weight=w, truth=x, noise=rng.standard_normal((5, n)))

    @property
    def n(self) -> int:
        return self.truth.shape[1]

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """Each star's normal equations, ``N0 (n, 5, 5)`` and ``b0 (n, 5)`` (star-last views),
        with the noise :meth:`prior_scan` adds (module notes): solved with any prior they give
        its solutions to rounding. A star whose position block is singular gets no noise."""
        from .scan_kernel import normal_noise  # numba only where it runs (prior_scan notes)

        n = self.n
        w2 = self.weight * self.weight
        N0 = np.zeros((5, 5, n))
        b0 = np.zeros((5, n))
        for u, w2_blk in zip(self.unit, w2):
            n_blk = u.T @ u
            N0 += n_blk[:, :, None] * w2_blk
            b0 += (n_blk[:, 2:] @ self.truth) * w2_blk
        noise = np.empty((5, n))
        normal_noise(N0, np.ascontiguousarray(self.noise), PIVOT_TOLERANCE, noise)
        return np.moveaxis(N0, -1, 0), (b0 + noise).T

    def prior_scan(self, ratio_R: float) -> PriorScan:
        """The prior-scan reduction of every star (:func:`mcsweep.astrometry.prior_scan.prior_scan`),
        without forming the ``(n, 5, 5)`` normal matrices."""
        from .scan_kernel import reduce_shared_design  # numba only where it runs (prior_scan notes)

        prior_diagonal(1.0, ratio_R)  # validates ratio_R
        n = self.n
        out = dict(x0=np.empty((2, n)), ainv=np.empty((3, n)), g=np.empty((2, 3, n)), c=np.empty((3, n)),
                   lam=np.empty((3, n)), ok=np.empty(n, dtype=bool))
        reduce_shared_design(self.unit, self.weight, self.truth, np.ascontiguousarray(self.noise), float(ratio_R),
                             PIVOT_TOLERANCE, out["x0"], out["ainv"], out["g"], out["c"], out["lam"], out["ok"])
        return PriorScan(ratio_R=float(ratio_R), **out)
