"""The evaluation of a primary solution, star by star and block by block (paper Sect. 4.2, step 5).

As the frame rotator: the rotation and spin fitted to (estimated - true) are removed
(Lindegren et al. 2012, Sect. 6.1), then each star is inside its P ellipse or not, with its
position error at the reference epoch (or its own mean epoch); the attitude error is the
estimated minus the true rotation after the same frame correction. Each function works on
one block (or on what one process holds), so a solution held in this process and one kept
on a cluster's workers are evaluated by the same code, summed in the same fixed tree.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...astrometry.confidence import inside as inside_ellipse
from ...astrometry.confidence import mahalanobis_sq
from ...solver import frame_attitude, precision_weights
from ...solver.blocks import spline_values
from ...solver.frame import frame_fit_sums, offsets_of
from .truth import block_epochs, rotation_at

__all__ = ["positions_at", "block_frame_sums", "block_outcome", "attitude_error",
           "attitude_error_series", "block_attitude_sq"]


def positions_at(x, cov, tau_yr) -> tuple[np.ndarray, np.ndarray]:
    """Position offsets (n, 2) [mas] and their covariances (n, 2, 2) at ``tau_yr`` Julian years
    from the reference epoch, from five-parameter offsets ``x (n, 5)`` and covariances
    ``cov (n, 5, 5)`` there: ``position + tau_yr * proper motion`` (Eq. 1's linear motion),
    exactly. The prior of Eq. 18 constrains only parallax and proper motion, so this equals a
    solution referred to the epoch ``tau_yr`` itself (tests)."""
    tau_yr = np.asarray(tau_yr, dtype=float)
    C = np.asarray(cov, dtype=float)
    pos = x[:, :2] + tau_yr[:, None] * x[:, 3:5]
    cov_pos = (C[:, :2, :2] + tau_yr[:, None, None] * (C[:, :2, 3:5] + C[:, 3:5, :2])
               + (tau_yr ** 2)[:, None, None] * C[:, 3:5, 3:5])
    return pos, cov_pos


def block_frame_sums(K, binv, dx, equal: bool) -> np.ndarray:
    """One block's part of the frame rotator's fit (Lindegren et al. 2012, Sect. 6.1): weighted
    by the formal precisions (``equal``: every star alike); unweighted, the arcsec errors of
    1-2-transit stars under 1000 mas set it. The same function wherever the block is."""
    return frame_fit_sums(K, np.ones((len(dx), 2)) if equal else precision_weights(binv), dx)


def block_outcome(K, binv, dx, eps, omega, tau_yr, confidence: float):
    """Per star of one block, after removing the fitted rotation ``eps`` and spin ``omega``:
    inside the P ellipse (1/0; -1 without a confidence region: the project's one inside rule),
    the position error [mas] (at ``tau_yr`` Julian years from the reference epoch if given) and
    the parallax error [mas]."""
    dx = dx - offsets_of(K, eps, omega)
    pos, cov_pos = dx[:, :2], binv[:, :2, :2]
    if tau_yr is not None:
        pos, cov_pos = positions_at(dx, binv, tau_yr)
    good = np.isfinite(mahalanobis_sq(pos, cov_pos))
    inside = np.full(len(dx), -1, dtype=np.int8)
    inside[good] = inside_ellipse(pos[good], cov_pos[good], confidence)
    return inside, np.hypot(pos[:, 0], pos[:, 1]), dx[:, 2].copy()


def attitude_error(data, coef, eps, omega, tcb_jd, estimated=None) -> np.ndarray:
    """Estimated minus true attitude after the frame correction at ``tcb_jd`` [mas], (m, 3);
    ``estimated``: the solution's attitude at ``tcb_jd`` if already known (m, 3)."""
    est = data.spline.evaluate(coef, tcb_jd) if estimated is None else estimated
    return est - data.true_attitude_at(tcb_jd) - frame_attitude(eps, omega, tcb_jd, data.t_ref_jd)


def attitude_error_series(data, coef, eps, omega, *, per_knot: int = 1) -> pd.DataFrame:
    """The attitude error on a regular grid (``per_knot`` points per knot interval, at
    interval centres), live time only (the spline has no segment in the dead time): columns ``tcb_jd``, ``x_uas``, ``y_uas``, ``z_uas``."""
    step = data.spline.knot_interval_days / per_knot
    t = data.spline.start_jd + step * (0.5 + np.arange(int(round((data.spline.end_jd - data.spline.start_jd)
                                                                   / step))))
    t = t[data.spline.segment_of(t) >= 0]  # live time: the spline's segments
    err = 1e3 * attitude_error(data, coef, eps, omega, t)
    return pd.DataFrame({"tcb_jd": t, "x_uas": err[:, 0].astype(np.float32), "y_uas": err[:, 1].astype(np.float32),
                         "z_uas": err[:, 2].astype(np.float32)})


def block_attitude_sq(block, coef, eps, omega, true_attitude, t_ref_jd) -> np.ndarray:
    """One block's sum of squared attitude errors (3,), from its own spline values."""
    t = block_epochs(t_ref_jd, block)
    err = spline_values(block, coef).T - rotation_at(true_attitude, t) - frame_attitude(eps, omega, t, t_ref_jd)
    return np.sum(err ** 2, axis=0)
