"""Design-matrix rows of the astrometric least-squares problem (paper Eq. 1).

For one star observed in ``k`` field-of-view (FoV) transits, each transit gives an
along-scan (AL) and optionally an across-scan (AC) measurement. Linearised about the
reference position, the displacement of the star from its reference direction at
time ``t`` (counted from the reference epoch, Sect. 2.1) is, in the tangent plane,

    d(t) = (dalpha* + mu_alpha* t - plx (p . b(t)),  ddelta + mu_delta t - plx (q . b(t)))

with ``b(t)`` the observer's barycentric position in au, ``p`` and ``q`` the unit
vectors towards local east and north at the star (the "normal triad", e.g. Lindegren
et al. 2012, A&A 538, A78), and parallax in mas so that ``plx * (au)`` is a
displacement in mas. A measurement projects ``d`` on the AL direction
``(sin psi, cos psi)`` or the AC direction ``(-cos psi, sin psi)`` in (east, north),
with ``psi`` the scan position angle (paper Table 1: the direction in which the FoV
moves across the star, 0 = local north, 90 deg = local east). Divided by the
measurement uncertainty, the coefficients of
``x = (dalpha*, ddelta, dplx, dmu_alpha*, dmu_delta)`` form one row of ``A`` (Eq. 1).

The epoch dependence of the normal triad, aberration and light deflection are
absorbed in the reference position and do not enter the differential corrections
(the paper's own model, Sect. 2.1); the perspective term of the radial proper motion
is neglected as the paper argues (Sect. 2.1, footnote 1).

Memory layout: :func:`~mcsweep.astrometry.design_matrix` returns an array of shape ``(n, m, 5)`` whose
memory is ordered ``(5, m, n)`` ("star-last"): every row/column element is a
contiguous vector over stars, which is what the batched solvers in
``mcsweep.astrometry.solve`` consume without copying. It behaves as any other
``(n, m, 5)`` array.
"""

from __future__ import annotations

import numpy as np

# The normal triad (p, q, r) of the star, Eq. 1 of Lindegren et al. (2012); one
# implementation, in the scanning stage's frames, re-exported here.
from ..scanning.frames import tangent_triad

__all__ = [
    "JULIAN_YEAR_DAYS",
    "N_PARAMETERS",
    "PARAMETER_NAMES",
    "tangent_triad",
    "reference_epoch",
    "years_since",
    "design_matrix",
]

#: Days per Julian year; ``t_yr`` everywhere is in Julian years.
JULIAN_YEAR_DAYS = 365.25

#: Order of the astrometric parameters (units mas, mas, mas, mas/yr, mas/yr).
PARAMETER_NAMES = ("dalpha_star_mas", "ddelta_mas", "parallax_mas", "pmra_mas_yr", "pmdec_mas_yr")
N_PARAMETERS = 5


def reference_epoch(tcb_jd, mask=None) -> np.ndarray:
    """Mean epoch of each star's observations (Sect. 2.1), as a TCB Julian date.

    Parameters
    ----------
    tcb_jd : array_like, shape (n, k)
        Transit epochs; entries where ``mask`` is False are ignored (may be NaN).
    mask : array_like of bool, shape (n, k), optional
        True where the transit exists; default all True.

    Returns
    -------
    ndarray, shape (n,)
        NaN for a star without transits.
    """
    t = np.asarray(tcb_jd, dtype=float)
    if t.ndim != 2:
        raise ValueError(f"tcb_jd must have shape (n, k), got {t.shape}")
    mask = np.ones(t.shape, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    if mask.shape != t.shape:
        raise ValueError(f"mask shape {mask.shape} does not match tcb_jd shape {t.shape}")
    count = mask.sum(axis=1)
    # Subtract a per-star origin first so the mean keeps full precision (JD ~ 2.46e6).
    origin = np.where(mask, t, np.inf).min(axis=1)
    origin = np.where(count > 0, origin, 0.0)
    total = np.where(mask, t - origin[:, None], 0.0).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, origin + total / count, np.nan)


def years_since(tcb_jd, epoch_tcb_jd) -> np.ndarray:
    """Time since the reference epoch in Julian years, ``(tcb_jd - epoch) / 365.25``.

    ``epoch_tcb_jd`` of shape (n,) is broadcast against ``tcb_jd`` of shape (n, k).
    """
    t = np.asarray(tcb_jd, dtype=float)
    ep = np.asarray(epoch_tcb_jd, dtype=float)
    if t.ndim == 2 and ep.ndim == 1:
        ep = ep[:, None]
    return (t - ep) / JULIAN_YEAR_DAYS


def design_matrix(ra_deg, dec_deg, t_yr, psi_deg, obs_au, *, sigma_al_mas, sigma_ac_mas=None,
                  mask=None) -> np.ndarray:
    """Normalised design matrix of Eq. 1 for many stars at once.

    Parameters
    ----------
    ra_deg, dec_deg : array_like, shape (n,)
        Reference direction of each star (ICRS), degrees.
    t_yr : array_like, shape (n, k)
        Transit times minus the star's reference epoch, Julian years.
    psi_deg : array_like, shape (n, k)
        Scan position angle psi of each transit, degrees (Table 1 convention).
    obs_au : array_like, shape (n, k, 3)
        Observer's barycentric (BCRS) position at each transit, au.
    sigma_al_mas : array_like, broadcastable to (n, k), keyword-only
        AL measurement uncertainty per FoV transit, mas.
    sigma_ac_mas : array_like, broadcastable to (n, k), optional, keyword-only
        AC measurement uncertainty per FoV transit, mas. None: AL rows only.
    mask : array_like of bool, shape (n, k), optional, keyword-only
        True where the transit exists; default all True. Inputs of absent transits
        are ignored (they may be NaN) and their rows are zero.

    Returns
    -------
    A : ndarray, shape (n, m, 5)
        ``m = k`` (AL only) or ``2 k`` (AL rows, then AC rows in the same transit
        order). Columns: (dalpha*, ddelta, dplx, dmu_alpha*, dmu_delta) in
        (mas, mas, mas, mas/yr, mas/yr), rows divided by the uncertainty, so ``A`` is
        dimensionless per mas. Memory is star-last (module notes).

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
    >>> A.shape
    (1, 4, 5)
    """
    ra = np.asarray(ra_deg, dtype=float)
    dec = np.asarray(dec_deg, dtype=float)
    t_yr = np.asarray(t_yr, dtype=float)
    psi_deg = np.asarray(psi_deg, dtype=float)
    obs_au = np.asarray(obs_au, dtype=float)
    if ra.ndim != 1 or dec.shape != ra.shape:
        raise ValueError(f"ra_deg and dec_deg must have the same shape (n,), got {ra.shape}, {dec.shape}")
    n = ra.shape[0]
    if t_yr.ndim != 2 or t_yr.shape[0] != n:
        raise ValueError(f"t_yr must have shape (n, k) with n={n}, got {t_yr.shape}")
    k = t_yr.shape[1]
    if psi_deg.shape != (n, k):
        raise ValueError(f"psi_deg must have shape {(n, k)}, got {psi_deg.shape}")
    if obs_au.shape != (n, k, 3):
        raise ValueError(f"obs_au must have shape {(n, k, 3)}, got {obs_au.shape}")
    mask = np.ones((n, k), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    if mask.shape != (n, k):
        raise ValueError(f"mask must have shape {(n, k)}, got {mask.shape}")

    # Work in (k, n) layout so every result row is a contiguous vector over stars.
    mask_t = np.ascontiguousarray(mask.T)
    all_present = bool(mask_t.all())
    w_al = _weights(sigma_al_mas, (n, k), mask_t, all_present, "sigma_al_mas")
    w_ac = None if sigma_ac_mas is None else _weights(sigma_ac_mas, (n, k), mask_t, all_present,
                                                      "sigma_ac_mas")
    t = np.ascontiguousarray(t_yr.T)
    psi = np.radians(psi_deg.T, order="C")
    obs = np.ascontiguousarray(obs_au.transpose(2, 1, 0))  # (3, k, n)
    if not all_present:  # inputs of absent transits may be NaN: neutralise them
        absent = ~mask_t
        t[absent] = 0.0
        psi[absent] = 0.0
        obs[:, absent] = 0.0

    a, d = np.radians(ra), np.radians(dec)
    sa, ca, sd, cd = np.sin(a), np.cos(a), np.sin(d), np.cos(d)
    # Observer position projected on east (p) and north (q): -plx * (pb, qb) is the
    # parallax displacement of the star in (alpha*, delta).
    pb = ca * obs[1]
    pb -= sa * obs[0]
    qb = ca * obs[0]
    qb += sa * obs[1]
    qb *= -sd
    qb += cd * obs[2]
    sin_psi, cos_psi = np.sin(psi), np.cos(psi)

    m = k if w_ac is None else 2 * k
    buf = np.empty((N_PARAMETERS, m, n))
    _fill_rows(buf[:, :k], sin_psi * w_al, cos_psi * w_al, pb, qb, t)  # AL: (sin psi, cos psi)
    if w_ac is not None:
        u = cos_psi * w_ac
        np.negative(u, out=u)
        _fill_rows(buf[:, k:], u, sin_psi * w_ac, pb, qb, t)  # AC: (-cos psi, sin psi)
    return buf.transpose(2, 1, 0)


def _fill_rows(out, u, v, pb, qb, t):
    """Rows for measurement direction (u, v) in (east, north), already divided by sigma."""
    out[0] = u
    out[1] = v
    np.multiply(qb, v, out=out[2])
    out[2] += pb * u
    np.negative(out[2], out=out[2])
    np.multiply(t, u, out=out[3])
    np.multiply(t, v, out=out[4])


def _weights(sigma, shape, mask_t, all_present, name) -> np.ndarray:
    """1/sigma in (k, n) layout, zero for absent transits; sigma must be positive."""
    s = np.asarray(sigma, dtype=float)
    n, k = shape
    if s.ndim == 2 and s.shape[1] == 1:  # one value per star: invert n numbers only
        s = np.broadcast_to(s[:, 0], (k, n))
    else:
        s = np.broadcast_to(s, shape).T
    present = s if all_present else s[mask_t]
    if present.size and not (np.isfinite(present).all() and (present > 0).all()):
        raise ValueError(f"{name} must be finite and positive for every present transit")
    w = np.divide(1.0, s, order="C") if all_present else np.where(mask_t, 1.0 / np.where(mask_t, s, 1.0), 0.0)
    return w
