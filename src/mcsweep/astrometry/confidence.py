"""Confidence regions of the estimated position and the statistics of actual errors.

A Gaussian position estimate with 2 x 2 covariance ``C`` has the confidence region
``Q = dpos' C^-1 dpos < k(P)`` where ``k(P)`` is the P-quantile of the chi-square
distribution with 2 degrees of freedom, ``k = -2 ln(1 - P)`` (4.605 for P = 0.9;
paper Sect. 2.4). The region is an ellipse whose semi-axes are ``sqrt(k)`` times the
square roots of the eigenvalues of ``C`` (Press et al. 2007, Numerical Recipes,
Sect. 15.6). The paper's criterion (Sect. 3.3) compares the fraction of stars whose
true position lies inside the ellipse with P, and the P-th percentile of the actual
position errors with the ellipse size.

The confidence level P is a parameter of every function (0 < P < 1).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import special

from ..errors import UserInputError

__all__ = [
    "check_probability",
    "chi2_threshold",
    "mahalanobis_sq",
    "inside",
    "fraction_inside",
    "inside_counts",
    "inside_components",
    "ellipse_semi_axes",
    "ellipse_position_angle_deg",
    "error_percentile",
    "binomial_interval",
    "percentile_interval",
]


def check_probability(P) -> float:
    """Return ``P`` as a float, or raise UserInputError unless 0 < P < 1."""
    try:
        p = float(P)
    except (TypeError, ValueError):
        raise UserInputError(f"confidence level P={P!r} is not accepted; expected a number strictly between 0 and 1")
    if not (0.0 < p < 1.0):
        raise UserInputError(f"confidence level P={P!r} is not accepted; expected a number strictly between 0 and 1")
    return p


def chi2_threshold(P, dof: int = 2) -> float:
    """Quantile ``k`` with ``Prob(chi2_dof < k) = P``; ``-2 ln(1 - P)`` for 2 dof.

    Parameters
    ----------
    P : float
        Confidence level, 0 < P < 1.
    dof : int
        Degrees of freedom (2 for a position).
    """
    p = check_probability(P)
    if int(dof) != dof or dof < 1:
        raise UserInputError(f"dof={dof!r} is not accepted; expected a positive integer")
    return _chi2_ppf(p, int(dof))


@lru_cache(maxsize=64)
def _chi2_ppf(p: float, dof: int) -> float:
    # Memoised: a sweep asks for the same quantile ~10^5 times. The chi-square quantile is
    # twice the inverse regularised lower incomplete gamma function at k/2 (what
    # scipy.stats.chi2.ppf evaluates), called here without importing scipy.stats (0.3 s of
    # every worker's start).
    return float(2.0 * special.gammaincinv(dof / 2, p))


def mahalanobis_sq(dpos, cov2) -> np.ndarray:
    """``Q = dpos' C^-1 dpos`` for every star.

    Parameters
    ----------
    dpos : array_like, shape (n, 2)
        Position error (estimated minus true), mas.
    cov2 : array_like, shape (n, 2, 2)
        Positional covariance, mas^2.

    Returns
    -------
    ndarray, shape (n,)
        NaN where the covariance is not positive definite or contains NaN.
    """
    d = np.asarray(dpos, dtype=float)
    c = np.asarray(cov2, dtype=float)
    if d.ndim != 2 or d.shape[1] != 2 or c.shape != (d.shape[0], 2, 2):
        raise ValueError(f"dpos must be (n, 2) and cov2 (n, 2, 2); got {d.shape} and {c.shape}")
    a, b, e = c[:, 0, 0], 0.5 * (c[:, 0, 1] + c[:, 1, 0]), c[:, 1, 1]
    det = a * e - b * b
    with np.errstate(invalid="ignore", divide="ignore"):
        q = (e * d[:, 0] ** 2 - 2.0 * b * d[:, 0] * d[:, 1] + a * d[:, 1] ** 2) / det
    q[~((det > 0) & (a > 0))] = np.nan
    return q


def inside(dpos, cov2, P) -> np.ndarray:
    """True where the true position lies inside the P confidence ellipse (``Q < k(P)``).

    Stars with a NaN error or an invalid covariance count as outside.
    """
    k = chi2_threshold(P, 2)
    q = mahalanobis_sq(dpos, cov2)
    with np.errstate(invalid="ignore"):
        return q < k


def inside_counts(dpos, cov2, P) -> tuple[int, int]:
    """Count the stars inside their P ellipse, and the stars that have one.

    The project's one NaN rule: a star whose error or covariance is not finite (an
    unsolved or flagged solution) has no confidence region, so it is left out of the
    denominator. Callers report ``n_valid`` next to the total so the exclusion is seen.

    Parameters
    ----------
    dpos : array_like, shape (n, 2)
        Position errors (estimated minus true, dalpha*, ddelta), mas.
    cov2 : array_like, shape (n, 2, 2)
        Their covariances, mas^2.
    P : float
        Confidence level of the ellipse, in (0, 1).

    Returns
    -------
    n_inside : int
        Stars whose error lies inside their P ellipse.
    n_valid : int
        Stars with a confidence region (finite error and covariance).

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.astrometry import inside_counts
    >>> dpos = np.array([[0.5, 0.0], [3.0, 0.0], [np.nan, 0.0]])  # mas
    >>> cov2 = np.tile(np.eye(2), (3, 1, 1))  # 1 mas^2 each
    >>> inside_counts(dpos, cov2, 0.9)  # the NaN star has no region
    (1, 2)
    """
    k = chi2_threshold(P, 2)
    q = mahalanobis_sq(dpos, cov2)
    valid = np.isfinite(q)
    return int(np.count_nonzero(q[valid] < k)), int(np.count_nonzero(valid))


def inside_components(dx, dy, caa, cad, cdd, P, *, inside_out=None, valid_out=None, work=None):
    """Per-star ``inside`` and ``valid`` flags from star-last components (hot loops).

    The rule of :func:`mahalanobis_sq`, :func:`inside` and :func:`inside_counts` for
    a position error ``(dx, dy)`` and covariance ``[[caa, cad], [cad, cdd]]`` given as
    separate arrays of one shape: ``valid`` where the covariance is positive definite
    and ``Q`` is finite, ``inside`` where valid and ``Q < k(P)``. The sums
    ``inside.sum(), valid.sum()`` are ``inside_counts`` of the same stars. Written for
    the prior scan's inner loop (:mod:`mcsweep.astrometry.prior_scan`): the optional
    boolean outputs and ``work`` (three float arrays and one bool array of the inputs'
    shape, overwritten) avoid every allocation.

    Returns
    -------
    inside, valid : ndarray of bool
    """
    k = chi2_threshold(P, 2)
    shape = np.shape(dx)
    if work is None:
        work = (np.empty(shape), np.empty(shape), np.empty(shape), np.empty(shape, dtype=bool))
    t1, t2, t3, flag = work
    valid = np.empty(shape, dtype=bool) if valid_out is None else valid_out
    ins = np.empty(shape, dtype=bool) if inside_out is None else inside_out
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        # Q det = dx (cdd dx - 2 cad dy) + caa dy^2, det = caa cdd - cad^2.
        np.multiply(cdd, dx, out=t1)
        np.multiply(cad, dy, out=t2)
        t2 *= 2.0
        t1 -= t2
        t1 *= dx
        np.multiply(caa, dy, out=t2)
        t2 *= dy
        t1 += t2
        np.multiply(caa, cdd, out=t2)
        np.multiply(cad, cad, out=t3)
        t2 -= t3
        np.divide(t1, t2, out=t1)
        np.greater(t2, 0.0, out=valid)
        np.greater(caa, 0.0, out=flag)
        valid &= flag
        np.isfinite(t1, out=flag)
        valid &= flag
        np.less(t1, k, out=ins)
    ins &= valid
    return ins, valid


def fraction_inside(dpos, cov2, P) -> float:
    """Fraction of stars inside their P confidence ellipse (NaN rule of :func:`inside_counts`).

    Parameters
    ----------
    dpos : array_like, shape (n, 2)
        Position errors (estimated minus true, dalpha*, ddelta), mas.
    cov2 : array_like, shape (n, 2, 2)
        Their covariances, mas^2.
    P : float
        Confidence level of the ellipse, in (0, 1).

    Returns
    -------
    float
        ``n_inside / n_valid``; NaN if no star has a valid confidence region.

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.astrometry import fraction_inside
    >>> dpos = np.array([[0.5, 0.0], [3.0, 0.0]])
    >>> cov2 = np.tile(np.eye(2), (2, 1, 1))
    >>> fraction_inside(dpos, cov2, 0.9)  # doctest: +FLOAT_CMP
    0.5
    """
    n_in, n_valid = inside_counts(dpos, cov2, P)
    return n_in / n_valid if n_valid else float("nan")


def ellipse_semi_axes(cov2, P) -> tuple[np.ndarray, np.ndarray]:
    """Semi-major and semi-minor axes (mas) of the P confidence ellipse.

    ``sqrt(k(P) * lambda)`` for the two eigenvalues ``lambda`` of each 2 x 2
    covariance, ``k(P)`` the chi-square quantile with two degrees of freedom.

    Parameters
    ----------
    cov2 : array_like, shape (n, 2, 2)
        Position covariances, mas^2.
    P : float
        Confidence level, in (0, 1).

    Returns
    -------
    semi_major, semi_minor : ndarray, shape (n,)
        The ellipses' axes, mas.

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.astrometry import ellipse_semi_axes
    >>> cov2 = np.array([[[4.0, 0.0], [0.0, 1.0]]])  # mas^2
    >>> a, b = ellipse_semi_axes(cov2, 0.9)
    >>> # sqrt(4.605 x 4) and sqrt(4.605): k(0.9) = 4.605
    >>> np.round(a, 3), np.round(b, 3)  # doctest: +FLOAT_CMP
    (array([4.292]), array([2.146]))
    """
    k = chi2_threshold(P, 2)
    c = np.asarray(cov2, dtype=float)
    if c.ndim != 3 or c.shape[1:] != (2, 2):
        raise ValueError(f"cov2 must have shape (n, 2, 2), got {c.shape}")
    a, b, e = c[:, 0, 0], 0.5 * (c[:, 0, 1] + c[:, 1, 0]), c[:, 1, 1]
    half_trace = 0.5 * (a + e)
    radius = np.hypot(0.5 * (a - e), b)
    lam_max = half_trace + radius
    # lambda_min = det / lambda_max avoids cancellation for very elongated ellipses.
    # Clipped to [0, lambda_max] against rounding (circular and degenerate cases).
    with np.errstate(invalid="ignore", divide="ignore"):
        lam_min = np.minimum((a * e - b * b) / lam_max, lam_max)
    return np.sqrt(k * lam_max), np.sqrt(k * np.clip(lam_min, 0.0, None))


def ellipse_position_angle_deg(cov2) -> np.ndarray:
    """Position angle of the ellipse's major axis, degrees from north through east, in [0, 180).

    For the covariance of (dalpha*, ddelta) = (east, north) components,
    ``PA = 0.5 atan2(2 C_ad, C_dd - C_aa)``.
    """
    c = np.asarray(cov2, dtype=float)
    pa = 0.5 * np.degrees(np.arctan2(2.0 * c[:, 0, 1], c[:, 1, 1] - c[:, 0, 0]))
    return np.mod(pa, 180.0)


def error_percentile(dpos, q) -> float:
    """The q-th percentile (0 <= q <= 100) of the actual position errors ``|dpos|``, mas.

    Rows with a NaN error are left out; NaN if none is left.
    """
    try:
        qf = float(q)
    except (TypeError, ValueError):
        raise UserInputError(f"percentile q={q!r} is not accepted; expected a number between 0 and 100")
    if not (0.0 <= qf <= 100.0):
        raise UserInputError(f"percentile q={q!r} is not accepted; expected a number between 0 and 100")
    d = np.asarray(dpos, dtype=float)
    if d.ndim != 2 or d.shape[1] != 2:
        raise ValueError(f"dpos must have shape (n, 2), got {d.shape}")
    r = np.hypot(d[:, 0], d[:, 1])
    r = r[np.isfinite(r)]
    return float(np.percentile(r, qf)) if r.size else float("nan")


def binomial_interval(n_inside, n_valid, level: float = 0.68) -> tuple[np.ndarray, np.ndarray]:
    """Clopper-Pearson interval of a fraction inside, ``n_inside`` of ``n_valid`` stars.

    Exact (conservative) binomial interval from the beta distribution (Clopper & Pearson
    1934, Biometrika 26, 404), central with probability ``level``; NaN where
    ``n_valid`` is 0. Arrays broadcast.
    """
    lv = check_probability(level)
    k = np.asarray(n_inside, dtype=float)
    n = np.asarray(n_valid, dtype=float)
    a = 0.5 * (1.0 - lv)
    from scipy import stats  # the interval's callers are reports, not the cells' workers

    with np.errstate(invalid="ignore", divide="ignore"):
        lo = np.where(k > 0, stats.beta.ppf(a, k, n - k + 1), 0.0)
        hi = np.where(k < n, stats.beta.ppf(1.0 - a, k + 1, n - k), 1.0)
    bad = ~(n > 0)
    return np.where(bad, np.nan, lo), np.where(bad, np.nan, hi)


def percentile_interval(errors, q, level: float = 0.68) -> tuple[float, float]:
    """Distribution-free interval of the q-th percentile of ``errors`` (order statistics).

    The interval between the order statistics whose ranks are the binomial quantiles
    of ``Bin(n, q/100)`` (Conover 1999, Practical Nonparametric Statistics, Sect. 3.2),
    central with probability at least ``level``; this is the interval of
    :func:`scipy.stats.quantile_test`, used here. Non-finite values are left out; NaN
    for an empty sample and for a bound beyond the sample (too few values for ``level``).
    """
    lv = check_probability(level)
    qf = float(q)
    if not (0.0 < qf < 100.0):
        raise UserInputError(f"percentile q={q!r} is not accepted; expected a number strictly between 0 and 100")
    x = np.asarray(errors, dtype=float).ravel()
    x = x[np.isfinite(x)]
    if x.size == 0:
        return float("nan"), float("nan")
    from scipy import stats  # see binomial_interval

    ci = stats.quantile_test(x, q=float(np.percentile(x, qf)), p=qf / 100.0).confidence_interval(lv)
    return float(ci.low), float(ci.high)
