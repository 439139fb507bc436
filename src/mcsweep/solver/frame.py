"""Reference frame: orientation and spin (Lindegren et al. 2012, Sect. 6.1).

Rotating all star positions by a small rotation vector ``eps`` and the attitude by
the same ``eps`` leaves every measurement unchanged; so does a spin ``omega`` added to
all proper motions with the attitude rotated by ``omega (t - t_ref)`` (the common
reference epoch ``t_ref``). The data therefore leave 6 degrees of freedom undetermined
(the prior on the proper motions, Eq. 18, fixes the spin only weakly).

* Constraint used in the solution: zero weighted mean rotation of the position
  corrections and of the proper-motion corrections over all sources,
  ``sum_i g_i K_i' dpos_i = 0`` and ``sum_i g'_i K_i' dmu_i = 0`` with ``g_i`` (``g'_i``)
  the star's formal position (proper-motion) precision normalised to mean 1
  (:func:`normalised_weights`, :class:`mcsweep.solver.problem.GlobalProblem`), added to the
  normal equations as a penalty whose weights are a typical star's (:func:`penalty_weights`) (exact for the orientation, whose direction the data do not see at all).
* Evaluation: as the frame rotator does after AGIS, the rotation and spin fitted by
  (weighted) least squares to (estimated - true) over all sources are removed before
  errors are computed (:func:`fit_frame`, :func:`frame_offsets`).

``K_i`` (2 x 3) maps ``eps`` to ``(dalpha*, ddelta) = (eps . q_i, -eps . p_i)`` with
``p, q`` local east and north (``eps x r`` projected on the tangent plane).
"""

from __future__ import annotations

import numpy as np

from ..astrometry.design import tangent_triad

__all__ = ["rotation_matrices", "frame_offsets", "fit_frame", "frame_attitude", "precision_weights",
           "frame_fit_sums", "frame_from_sums", "offsets_of", "weight_sums", "normalised_weights", "typical_weights",
           "penalty_weights"]


def rotation_matrices(ra_deg, dec_deg) -> np.ndarray:
    """``K (n, 2, 3)``: position offsets (dalpha*, ddelta) of a rotation vector (module notes)."""
    p, q, _ = tangent_triad(ra_deg, dec_deg)
    return np.stack([q, -p], axis=-2)


def frame_offsets(ra_deg, dec_deg, eps_mas, omega_mas_yr) -> np.ndarray:
    """Parameter offsets ``(n, 5)`` of a rotation ``eps`` [mas] and spin ``omega`` [mas/yr]."""
    K = rotation_matrices(ra_deg, dec_deg)
    out = np.zeros(K.shape[:1] + (5,))
    out[:, 0:2] = K @ np.asarray(eps_mas, dtype=float)
    out[:, 3:5] = K @ np.asarray(omega_mas_yr, dtype=float)
    return out


def precision_weights(cov) -> np.ndarray:
    """Each source's formal precision of position and of proper motion, (n, 2).

    ``2 / (C_aa + C_dd)`` and ``2 / (C_mu_a* mu_a* + C_mu_d mu_d)`` from the 5 x 5
    covariances ``cov`` (n, 5, 5): the weights of the frame constraint and of the frame
    rotator's fit (Lindegren et al. 2012, Sect. 6.1), so that sources without
    proper-motion information do not set the spin.
    """
    c = np.asarray(cov, dtype=float)
    return np.column_stack([2.0 / (c[:, 0, 0] + c[:, 1, 1]), 2.0 / (c[:, 3, 3] + c[:, 4, 4])])


def fit_frame(dx, ra_deg, dec_deg, select=None, weights=None) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rotation ``eps`` [mas] and spin ``omega`` [mas/yr] of parameter differences.

    Parameters
    ----------
    dx : array_like (n, 5)
        Estimated minus true parameters.
    ra_deg, dec_deg : array_like (n,)
    select : array_like of bool (n,), optional
        Sources used in the fit (default all with finite ``dx``).
    weights : array_like (n, 2), optional
        Weights of each source's position and proper-motion offsets, e.g. their formal
        precisions ``2 / (C_aa + C_dd)`` (the frame rotator's weighted fit, Lindegren et
        al. 2012, Sect. 6.1). Default equal weights. With loose priors the equal-weight
        fit is dominated by the stars whose positions and proper motions the data leave
        free (errors of arcsec under a 1000 mas prior) and removes a spurious rotation
        and spin from every star.
    """
    dx = np.asarray(dx, dtype=float)
    K = rotation_matrices(ra_deg, dec_deg)
    sel = np.all(np.isfinite(dx), axis=1) if select is None else np.asarray(select, dtype=bool)
    w = np.ones((dx.shape[0], 2)) if weights is None else np.asarray(weights, dtype=float)
    Ks, ws = K[sel], w[sel]
    out = []
    for col, wk in ((0, ws[:, 0]), (3, ws[:, 1])):
        M = np.einsum("n,nij,nik->jk", wk, Ks, Ks)
        out.append(np.linalg.solve(M, np.einsum("n,nij,ni->j", wk, Ks, dx[sel, col:col + 2])))
    return out[0], out[1]


def frame_fit_sums(K, w, dx) -> np.ndarray:
    """The normal equations of :func:`fit_frame` over one block of stars, (24,): ``M`` (3 x 3)
    and right-hand side (3,) of the rotation, then of the spin, from the rotation matrices
    ``K (n, 2, 3)``, weights ``w (n, 2)`` and differences ``dx (n, 5)``. Sums of blocks
    (in a fixed order) give the fit over all stars wherever the blocks are
    (:func:`frame_from_sums`)."""
    out = []
    for col, wk in ((0, w[:, 0]), (3, w[:, 1])):
        WK = wk[:, None, None] * K
        out += [np.sum(WK[:, :, :, None] * K[:, :, None, :], axis=(0, 1)).ravel(),
                np.sum(WK * dx[:, col:col + 2, None], axis=(0, 1))]
    return np.concatenate(out)


def frame_from_sums(sums) -> tuple[np.ndarray, np.ndarray]:
    """Rotation ``eps`` [mas] and spin ``omega`` [mas/yr] from summed :func:`frame_fit_sums`."""
    s = np.asarray(sums, dtype=float)
    return (np.linalg.solve(s[0:9].reshape(3, 3), s[9:12]), np.linalg.solve(s[12:21].reshape(3, 3), s[21:24]))


def offsets_of(K, eps_mas, omega_mas_yr) -> np.ndarray:
    """:func:`frame_offsets` from rotation matrices ``K (n, 2, 3)`` (element by element)."""
    out = np.zeros(K.shape[:1] + (5,))
    for i in range(3):
        out[:, 0:2] += K[:, :, i] * eps_mas[i]
        out[:, 3:5] += K[:, :, i] * omega_mas_yr[i]
    return out


def frame_attitude(eps_mas, omega_mas_yr, tcb_jd, t_ref_jd: float) -> np.ndarray:
    """Attitude rotation (m, 3) [mas] matching a frame rotation ``eps`` and spin ``omega``."""
    t_yr = (np.asarray(tcb_jd, dtype=float) - t_ref_jd) / 365.25
    return np.asarray(eps_mas, dtype=float) + t_yr[:, None] * np.asarray(omega_mas_yr, dtype=float)


def weight_sums(g) -> np.ndarray:
    """Column sums (2,) of one block's frame weights ``g (n, 2)`` (summed over blocks in the
    fixed tree, so the means are the same bits wherever the blocks are)."""
    return np.array([np.sum(g[:, 0]), np.sum(g[:, 1])])


def normalised_weights(g, means) -> np.ndarray:
    """Frame constraint weights (module notes): each star's formal precision of position and
    proper motion (attitude as known, :func:`precision_weights`), normalised to mean 1."""
    return np.column_stack([g[:, 0] / means[0], g[:, 1] / means[1]])


def typical_weights(N_src, prior) -> tuple[np.ndarray, np.ndarray]:
    """Per star, its position and proper-motion weights (data and prior) whose medians set the
    frame penalty (:func:`penalty_weights`)."""
    return N_src[:, 0, 0] + N_src[:, 1, 1], N_src[:, 3, 3] + N_src[:, 4, 4] + 2 * prior[:, 3]


def penalty_weights(pos, pm, n: int) -> tuple[float, float]:
    """Frame penalty weights: one typical star's position (proper-motion) weight per unit of
    mean rotation, so the constrained directions are as well conditioned as a star (any
    positive weight gives the same stars for the orientation). ``pos``, ``pm``: the stars'
    weights' medians (of :func:`typical_weights`; on a cluster found by
    :mod:`mcsweep.solver.selection`)."""
    return float(pos) / (2.0 * n), float(pm) / (2.0 * n)
