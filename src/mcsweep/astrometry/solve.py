"""Least-squares and Bayesian solutions for the astrometric parameters (Sect. 2).

With the normalised design matrix ``A`` and measurements ``h`` of Eq. 1,

* the normal equations are ``N0 x0 = b0`` with ``N0 = A'A``, ``b0 = A'h`` (Eqs. 2-3);
* a Gaussian prior with mean ``x_p`` and normal matrix ``N_p = C_p^-1`` (Eqs. 8-9) gives
  the posterior mean from ``(N0 + N_p) x = b0 + b_p``, ``b_p = N_p x_p`` (Eqs. 11-12),
  and the posterior covariance ``C = (N0 + N_p)^-1`` (Eq. 13);
* the paper's prior is centred on zero (``b_p = 0``) with
  ``N_p = diag(0, 0, sigma_plx^-2, sigma_mu^-2, sigma_mu^-2)``,
  ``sigma_mu = R sigma_plx`` and ``R = 10 /yr`` (Eq. 18, Sect. 3.1).

All functions work on stacks of stars, ``N0`` of shape (n, 5, 5) and ``b0`` (n, 5),
through the batched Cholesky solver of :mod:`mcsweep.astrometry.linalg`; results are
returned in star-last memory layout (see :mod:`mcsweep.astrometry.design`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserInputError
from .linalg import spd_solve

__all__ = [
    "DEFAULT_RATIO_R",
    "DEFAULT_MAX_CONDITION",
    "Solution",
    "normal_equations",
    "prior_diagonal",
    "solve_with_prior",
    "solve_position_only",
    "solve_no_prior",
]

#: R = sigma_mu,p / sigma_plx,p in 1/yr (paper Sect. 3.1, used in Eq. 18).
DEFAULT_RATIO_R = 10.0

#: Largest accepted 1-norm condition number of the unit-diagonal normal matrix for a
#: solution without prior. Rounding alone would allow ~1e12 (four significant digits
#: left with eps = 2.2e-16), but well before that the solution is fixed by fewer
#: independent epochs/directions than parameters and its formal errors are hundreds of
#: times those of the best-determined combination. For the paper's Table 1 geometry
#: (G = 15, our noise model) the condition numbers are: 2 distinct transits with AC
#: 6e8 (first two) and 8e7 (first and last); 3 distinct with AC 5e4; 3 distinct AL only
#: 1e8; 4 distinct AL only 2e5; all 8 distinct 24. The threshold 1e6 therefore flags
#: exactly the cases the paper calls insufficient (Sect. 3.3: two distinct transits
#: never suffice; three suffice if AL and AC are both used).
DEFAULT_MAX_CONDITION = 1e6

# Stars per block when forming normal equations (measured fastest on a 512 kB L2 cache).
_NORMAL_BLOCK = 8192


@dataclass(frozen=True)
class Solution:
    """Astrometric solutions of many stars.

    Parameters
    ----------
    x : ndarray, shape (n, 5)
        Estimated (dalpha*, ddelta, dplx, dmu_alpha*, dmu_delta) in
        (mas, mas, mas, mas/yr, mas/yr). Parameters not solved for (position-only
        solutions) are exactly 0. NaN where ``ok`` is False.
    cov : ndarray, shape (n, 5, 5)
        Covariance (posterior covariance for prior solutions, Eq. 13); rows and columns
        of parameters not solved for are 0. NaN where ``ok`` is False.
    ok : ndarray of bool, shape (n,)
        False where the normal matrix was singular (or, without prior, ill-conditioned).
    condition : ndarray, shape (n,), or None
        1-norm condition number of the solved normal matrix scaled to unit diagonal
        (``mcsweep.astrometry.linalg``); ``inf`` where singular. None when not
        computed (:func:`solve_with_prior` without ``with_condition=True``).

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.astrometry import normal_equations
    >>> # one star, five measurements (rows: one parameter each, 0.5 mas)
    >>> A = np.eye(5)[None] * 2.0
    >>> N0, b0 = normal_equations(A, A @ np.array([1.0, -1.0, 2.0, 3.0, 0.0]))
    >>> from mcsweep.astrometry import solve_with_prior
    >>> sol = solve_with_prior(N0, b0, 1.0)
    >>> sol.x.shape, sol.cov.shape, bool(sol.ok[0])
    ((1, 5), (1, 5, 5), True)
    """

    x: np.ndarray
    cov: np.ndarray
    ok: np.ndarray
    condition: np.ndarray | None = None

    @property
    def position(self) -> np.ndarray:
        """(dalpha*, ddelta) in mas, shape (n, 2).

        Examples
        --------
        >>> import numpy as np
        >>> from mcsweep.astrometry import solve_with_prior
        >>> # one star, 0.5 mas per parameter without a prior
        >>> N0 = np.eye(5)[None] * 4.0
        >>> b0 = np.array([[2.0, -1.0, 0.0, 0.0, 0.0]])
        >>> sol = solve_with_prior(N0, b0, 1.0)
        >>> sol.position  # (dalpha*, ddelta), mas  # doctest: +FLOAT_CMP
        array([[ 0.5 , -0.25]])
        """
        return self.x[:, :2]

    @property
    def position_cov(self) -> np.ndarray:
        """Positional 2 x 2 covariance in mas^2, shape (n, 2, 2).

        Examples
        --------
        >>> import numpy as np
        >>> from mcsweep.astrometry import solve_with_prior
        >>> # one star, 0.5 mas per parameter without a prior
        >>> N0 = np.eye(5)[None] * 4.0
        >>> b0 = np.array([[2.0, -1.0, 0.0, 0.0, 0.0]])
        >>> sol = solve_with_prior(N0, b0, 1.0)
        >>> sol.position_cov  # mas^2  # doctest: +FLOAT_CMP
        array([[[0.25, 0.  ],
                [0.  , 0.25]]])
        """
        return self.cov[:, :2, :2]


def normal_equations(A, h) -> tuple[np.ndarray, np.ndarray]:
    """Normal matrix ``N0 = A'A`` and right-hand side ``b0 = A'h`` (Eqs. 2-3).

    Parameters
    ----------
    A : array_like, shape (n, m, 5)
        Normalised design matrix; zero rows (absent transits) contribute nothing.
    h : array_like, shape (n, m)
        Normalised measurements.

    Returns
    -------
    N0 : ndarray, shape (n, 5, 5)
        Normal matrices ``A'A`` (star-last memory layout).
    b0 : ndarray, shape (n, 5)
        Right-hand sides ``A'h`` (star-last memory layout).

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.astrometry import design_matrix, normal_equations
    >>> # four transits: years from the reference epoch, scan angles [deg]
    >>> t = np.array([[-0.4, -0.1, 0.2, 0.45]])
    >>> psi = np.array([[10.0, 80.0, 150.0, 260.0]])
    >>> # the observer on a circle of 1 au [au]
    >>> ph = 2 * np.pi * t[..., None]
    >>> obs = np.concatenate([np.cos(ph), np.sin(ph), 0 * ph], axis=-1)
    >>> A = design_matrix([150.0], [20.0], t, psi, obs, sigma_al_mas=0.1)
    >>> # noiseless measurements of a star (plx 2 mas, pm 1, -3 mas/yr)
    >>> h = A @ np.array([0.0, 0.0, 2.0, 1.0, -3.0])
    >>> N0, b0 = normal_equations(A, h)
    >>> N0.shape, b0.shape
    ((1, 5, 5), (1, 5))
    """
    A = np.asarray(A, dtype=float)
    h = np.asarray(h, dtype=float)
    if A.ndim != 3 or A.shape[2] != 5:
        raise ValueError(f"A must have shape (n, m, 5), got {A.shape}")
    if h.shape != A.shape[:2]:
        raise ValueError(f"h must have shape {A.shape[:2]}, got {h.shape}")
    n, _, p = A.shape
    # Star-last views (5, m, n) and (m, n): no copy for arrays from design_matrix and
    # simulate. Blocks of stars keep the operands in cache.
    At = A.transpose(2, 1, 0)
    ht = h.T
    if not (At.flags.c_contiguous and ht.flags.c_contiguous):
        At, ht = np.ascontiguousarray(At), np.ascontiguousarray(ht)
    N0 = np.empty((p, p, n))
    b0 = np.empty((p, n))
    for start in range(0, n, _NORMAL_BLOCK):
        sl = slice(start, min(start + _NORMAL_BLOCK, n))
        for i in range(p):
            for j in range(i + 1):
                np.einsum("rn,rn->n", At[i, :, sl], At[j, :, sl], out=N0[i, j, sl])
        np.einsum("irn,rn->in", At[:, :, sl], ht[:, sl], out=b0[:, sl])
    for i in range(p):
        for j in range(i):
            N0[j, i] = N0[i, j]
    return np.moveaxis(N0, -1, 0), b0.T


def prior_diagonal(sigma_plx_prior_mas, ratio_R=DEFAULT_RATIO_R) -> np.ndarray:
    """Diagonal of the prior normal matrix N_p of Eq. 18.

    Parameters
    ----------
    sigma_plx_prior_mas : float or array_like, shape (n,)
        Prior standard deviation of the parallax, mas (positive; ``inf`` = no prior).
    ratio_R : float or array_like, shape (n,)
        ``sigma_mu,p / sigma_plx,p`` in 1/yr (Sect. 3.1; positive).

    Returns
    -------
    ndarray, shape (5,) or (n, 5)
        ``(0, 0, sigma_plx^-2, sigma_mu^-2, sigma_mu^-2)`` in mas^-2 and (mas/yr)^-2.
    """
    s = np.asarray(sigma_plx_prior_mas, dtype=float)
    r = np.asarray(ratio_R, dtype=float)
    if s.ndim > 1 or not np.all(s > 0):
        raise UserInputError(
            f"sigma_plx_prior_mas={_short(s)} is not accepted; expected a positive number of mas "
            "(or one per star)")
    if r.ndim > 1 or not np.all((r > 0) & np.isfinite(r)):
        raise UserInputError(f"ratio_R={_short(r)} is not accepted; expected a positive finite number per year")
    s, r = np.broadcast_arrays(s, r)
    w_plx = 1.0 / s**2
    w_mu = w_plx / r**2
    zero = np.zeros_like(w_plx)
    return np.stack([zero, zero, w_plx, w_mu, w_mu], axis=-1)


def solve_with_prior(N0, b0, sigma_plx_prior_mas, ratio_R=DEFAULT_RATIO_R, *,
                     with_condition: bool = False, prior_mean=None) -> Solution:
    """Five-parameter solution with a Gaussian prior, centred on zero by default (Eqs. 11-13, 18).

    ``x = (N0 + N_p)^-1 b0`` and ``C = (N0 + N_p)^-1`` with
    ``N_p = diag(0, 0, sigma_plx^-2, sigma_mu^-2, sigma_mu^-2)``, ``sigma_mu = R sigma_plx``.
    With ``prior_mean`` = x_p the right-hand side is ``b0 + N_p x_p`` (Eqs. 11-12); the
    covariance is unchanged.
    The prior leaves the position unconstrained, so a star whose data cannot fix the
    position (e.g. AL measurements in a single scan direction) is still singular and
    gets ``ok = False``.

    Parameters
    ----------
    N0 : array_like, shape (n, 5, 5)
        Normal matrices of Eq. 2, parameters (dalpha*, ddelta, parallax, pmra*, pmdec) in
        (mas, mas, mas, mas/yr, mas/yr).
    b0 : array_like, shape (n, 5)
        Right-hand sides of Eq. 3, same units.
    sigma_plx_prior_mas : float or array_like, shape (n,)
        Prior parallax standard deviation, mas: one value or one per star.
    ratio_R : float or array_like, shape (n,)
        ``sigma_mu,p / sigma_plx,p`` in 1/yr; default 10 (Sect. 3.1).
    with_condition : bool, keyword-only
        Also compute ``Solution.condition`` (about 30 % more time).
    prior_mean : array_like, shape (5,) or (n, 5), keyword-only
        Centre x_p of the prior, parameter order as ``x`` (mas, mas/yr); its position
        components are multiplied by the prior's zero weights and so have no effect.
        None (default): centred on zero, the paper's prior (Sect. 3.1).

    Returns
    -------
    Solution
        The posterior mean and covariance of every star (Eq. 13).

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.astrometry import normal_equations
    >>> # one star, five measurements (rows: one parameter each, 0.5 mas)
    >>> A = np.eye(5)[None] * 2.0
    >>> N0, b0 = normal_equations(A, A @ np.array([1.0, -1.0, 2.0, 3.0, 0.0]))
    >>> from mcsweep.astrometry import solve_with_prior
    >>> sol = solve_with_prior(N0, b0, sigma_plx_prior_mas=1.0)  # R = 10/yr
    >>> np.round(sol.x[0], 3)  # the parallax pulled towards 0  # doctest: +FLOAT_CMP
    array([ 1.   , -1.   ,  1.6  ,  2.993,  0.   ])
    >>> np.round(np.sqrt(np.diag(sol.cov[0])), 3)  # doctest: +FLOAT_CMP
    array([0.5  , 0.5  , 0.447, 0.499, 0.499])
    """
    N0, b0 = check_normal(N0, b0)
    diag = prior_diagonal(sigma_plx_prior_mas, ratio_R)
    if diag.ndim == 2 and diag.shape[0] != N0.shape[0]:
        raise ValueError(f"{diag.shape[0]} prior values for {N0.shape[0]} stars")
    if prior_mean is not None:
        m = np.asarray(prior_mean, dtype=float)
        if m.shape not in ((5,), (N0.shape[0], 5)):
            raise UserInputError(f"prior_mean of shape {m.shape} is not accepted; expected (5,) or "
                                 f"{(N0.shape[0], 5)} (mas, mas/yr per parameter)")
        if not np.all(np.isfinite(m)):
            raise UserInputError("prior_mean has NaN or infinite values; expected finite mas and mas/yr")
        b0 = b0 + diag * m
    x, cov, ok, cond = spd_solve(N0, b0, add_diagonal=diag, with_condition=with_condition)
    return Solution(x=x, cov=cov, ok=ok, condition=cond)


def solve_position_only(N0, b0) -> Solution:
    """Two-parameter solution: position only, parallax and proper motion fixed at 0.

    This is the tight-prior limit of :func:`solve_with_prior` and the "none
    (2 parameters)" row of the paper's Table 2.

    Parameters
    ----------
    N0 : array_like, shape (n, 5, 5)
        Normal matrices of Eq. 2, parameters (dalpha*, ddelta, parallax, pmra*, pmdec) in
        (mas, mas, mas, mas/yr, mas/yr).
    b0 : array_like, shape (n, 5)
        Right-hand sides of Eq. 3, same units.

    Returns
    -------
    Solution
        ``x`` and ``cov`` in the five-parameter shape, with zeros for the three fixed
        parameters.

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.astrometry import normal_equations
    >>> # one star, five measurements (rows: one parameter each, 0.5 mas)
    >>> A = np.eye(5)[None] * 2.0
    >>> N0, b0 = normal_equations(A, A @ np.array([1.0, -1.0, 2.0, 3.0, 0.0]))
    >>> from mcsweep.astrometry import solve_position_only
    >>> np.round(solve_position_only(N0, b0).x[0], 3)
    array([ 1., -1.,  0.,  0.,  0.])
    """
    N0, b0 = check_normal(N0, b0)
    x2, cov2, ok, cond = spd_solve(N0[:, :2, :2], b0[:, :2], with_condition=True)
    n = N0.shape[0]
    x = np.zeros((5, n)).T
    cov = np.moveaxis(np.zeros((5, 5, n)), -1, 0)
    x[:, :2] = x2
    cov[:, :2, :2] = cov2
    x[~ok] = np.nan
    cov[~ok] = np.nan
    return Solution(x=x, cov=cov, ok=ok, condition=cond)


def solve_no_prior(N0, b0, max_condition=DEFAULT_MAX_CONDITION) -> Solution:
    """Five-parameter least-squares solution without prior (Eqs. 2-3).

    Stars whose normal matrix is singular, or whose condition number (1-norm, after
    scaling to unit diagonal) exceeds ``max_condition``, get ``ok = False`` and NaN
    instead of numbers (Sect. 2.1: such solutions are not determined by the data).

    Parameters
    ----------
    N0 : array_like, shape (n, 5, 5)
        Normal matrices of Eq. 2, parameters (dalpha*, ddelta, parallax, pmra*, pmdec) in
        (mas, mas, mas, mas/yr, mas/yr).
    b0 : array_like, shape (n, 5)
        Right-hand sides of Eq. 3, same units.
    max_condition : float
        Largest accepted condition number; default ``DEFAULT_MAX_CONDITION``.

    Returns
    -------
    Solution
        The least-squares estimate and its covariance ``N0^-1``.

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.astrometry import solve_no_prior
    >>> N0 = np.diag([4.0, 4.0, 4.0, 4.0, 0.0])[None]  # pmdec not measured
    >>> sol = solve_no_prior(N0, np.ones((1, 5)))
    >>> bool(sol.ok[0]), bool(np.isnan(sol.x).all())
    (False, True)
    """
    if not (np.isscalar(max_condition) and max_condition >= 1.0):
        raise UserInputError(f"max_condition={max_condition!r} is not accepted; expected a number >= 1")
    N0, b0 = check_normal(N0, b0)
    x, cov, ok, cond = spd_solve(N0, b0, with_condition=True)
    ill = ok & ~(cond <= max_condition)
    if ill.any():
        ok = ok & ~ill
        x[ill] = np.nan
        cov[ill] = np.nan
    return Solution(x=x, cov=cov, ok=ok, condition=cond)


def check_normal(N0, b0):
    N0 = np.asarray(N0, dtype=float)
    b0 = np.asarray(b0, dtype=float)
    if N0.ndim != 3 or N0.shape[1:] != (5, 5):
        raise ValueError(f"N0 must have shape (n, 5, 5), got {N0.shape}")
    if b0.shape != N0.shape[:2]:
        raise ValueError(f"b0 must have shape {N0.shape[:2]}, got {b0.shape}")
    return N0, b0


def _short(a) -> str:
    a = np.asarray(a)
    if a.size <= 3:
        return repr(a.tolist())
    bad = a[~(a > 0)] if np.any(~(a > 0)) else a
    return f"array with {bad.size} unacceptable value(s), e.g. {bad.flat[0]!r}"
