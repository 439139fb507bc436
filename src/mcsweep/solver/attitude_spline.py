"""Cubic B-spline basis in time for the attitude corrections (Lindegren et al. 2012, Sect. 3.3).

AGIS represents the four quaternion components as cubic B-splines in time. At the
accuracy of this simulation the attitude is the scanning law plus a *small* rotation,
so we model only the correction: a rotation vector ``delta(t)`` (three components, ICRS
axes, mas), each component a cubic spline on one knot sequence. To first order in
``|delta|`` (~1e-8 rad here, second-order terms ~1e-16 rad) this is the same model as
a quaternion spline linearised about the scanning-law attitude.

Why ICRS axes rather than the spacecraft axes: a constant rotation and a rotation
growing linearly in time are then exactly in the spline space (B-splines sum to one;
a linear function has the Greville abscissae as coefficients), so the 6-dof frame
degeneracy (orientation and spin, Lindegren et al. 2012, Sect. 6.1) is exact, as in
AGIS, and can be fixed by a constraint and removed by the frame rotator
(:mod:`mcsweep.solver.frame`).

Knots: a uniform sequence of interval ``knot_interval_days`` over ``[start, end]``,
clamped (end knots repeated 4 times). Each epoch touches 4 consecutive coefficients.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import BSpline

__all__ = ["AttitudeSpline", "DEGREE"]

#: Cubic splines, as AGIS (Lindegren et al. 2012, Sect. 3.3).
DEGREE = 3


class AttitudeSpline:
    """Clamped cubic B-spline basis with uniform knots.

    Parameters
    ----------
    start_jd, end_jd : float
        Interval covered (TCB JD) [day].
    knot_interval_days : float
        Knot interval [day].
    """

    def __init__(self, start_jd: float, end_jd: float, knot_interval_days: float):
        if not (end_jd > start_jd and knot_interval_days > 0):
            raise ValueError(f"need end_jd > start_jd and knot_interval_days > 0, got {start_jd}, {end_jd}, "
                             f"{knot_interval_days}")
        n_int = max(1, math.ceil((end_jd - start_jd) / knot_interval_days - 1e-9))
        self.start_jd = float(start_jd)
        self.knot_interval_days = float(knot_interval_days)
        self.end_jd = self.start_jd + n_int * self.knot_interval_days
        inner = self.start_jd + self.knot_interval_days * np.arange(n_int + 1)
        self.knots = np.concatenate([np.full(DEGREE, inner[0]), inner, np.full(DEGREE, inner[-1])])
        self.n_coef = n_int + DEGREE

    def basis(self, tcb_jd) -> tuple[np.ndarray, np.ndarray]:
        """First coefficient index ``j0 (m,)`` and the 4 non-zero basis values ``(m, 4)``.

        The basis functions ``j0, j0 + 1, j0 + 2, j0 + 3`` are the only non-zero ones at
        each epoch (from :meth:`scipy.interpolate.BSpline.design_matrix`).
        """
        t = np.asarray(tcb_jd, dtype=float).ravel()
        if t.size and (t.min() < self.start_jd or t.max() > self.end_jd):
            raise ValueError("epochs outside the spline interval")
        if t.size == 0:
            return np.empty(0, dtype=np.int64), np.empty((0, DEGREE + 1))
        dm = BSpline.design_matrix(t, self.knots, DEGREE).tocsr()
        dm.sort_indices()
        counts = np.diff(dm.indptr)
        if not np.all(counts == DEGREE + 1):  # pragma: no cover - scipy contract
            raise RuntimeError("unexpected B-spline design matrix structure")
        idx = dm.indices.reshape(-1, DEGREE + 1)
        return idx[:, 0].astype(np.int64), dm.data.reshape(-1, DEGREE + 1).copy()

    def evaluate(self, coef, tcb_jd) -> np.ndarray:
        """Spline value ``(m, c)`` at ``tcb_jd`` for coefficients ``coef (n_coef, c)``."""
        j0, b = self.basis(tcb_jd)
        coef = np.asarray(coef, dtype=float)
        out = np.zeros((j0.size,) + coef.shape[1:])
        for k in range(DEGREE + 1):
            out += b[:, k, None] * coef[j0 + k]
        return out

    def greville(self) -> np.ndarray:
        """Greville abscissae (n_coef,): coefficients that reproduce ``f(t) = t`` exactly."""
        window = np.convolve(self.knots, np.full(DEGREE, 1.0 / DEGREE), mode="valid")
        return window[1:self.n_coef + 1]
