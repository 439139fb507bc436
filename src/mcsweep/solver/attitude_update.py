"""The attitude block of AGIS: banded normal equations of the spline coefficients.

Unknowns are ordered coefficient by coefficient, the three axes interleaved (index
``3 j + axis``). A cubic B-spline coefficient couples only to its 3 neighbours on each
side, so every measurement touches 12 consecutive unknowns and the attitude normal
matrix is banded with ``BANDWIDTH = 11`` super-diagonals (Lindegren et al. 2012,
Sect. 5.3). It is stored in LAPACK's upper band form (``ab[u + i - j, j] = N[i, j]``)
for :func:`scipy.linalg.cholesky_banded` / :func:`scipy.linalg.cho_solve_banded`.

Coefficients whose support holds no measurement (inside dead time) are not
determined by the data; they are held at zero (unit diagonal, zero right-hand side),
as AGIS breaks the attitude into segments at data gaps.
"""

from __future__ import annotations

import numpy as np

from . import kernel_backend
from .observations import Measurements

__all__ = ["BANDWIDTH", "band_of_rows", "attitude_band", "band_to_dense", "free_coefficients"]

_AX = 3
_NB = 4  # basis functions per epoch (cubic)
#: Super-diagonals of the attitude normal matrix (12 consecutive unknowns per measurement).
BANDWIDTH = _AX * _NB - 1


def band_of_rows(j0, rows, n_coef: int) -> np.ndarray:
    """Upper band storage ``(BANDWIDTH + 1, 3 n_coef)`` of ``sum g' g`` over attitude rows.

    ``rows`` (m, 12): each measurement's partials w.r.t. unknowns ``3 j0 .. 3 j0 + 11``
    (B-spline value times axis partial). Each band element sums its rows in row order (the
    bits of one :func:`numpy.bincount` per element, compiled so that it touches only the
    rows' unknowns: :func:`~mcsweep.solver.kernels.band_scatter`).
    """
    n = _AX * int(n_coef)
    g = np.asarray(rows, dtype=float).T[None]  # (1, 12, m)
    ab = np.zeros((BANDWIDTH + 1, n))
    kernel_backend.active().band_scatter(ab, g, g, _AX * np.asarray(j0, dtype=np.int64))
    return ab


def attitude_band(obs: Measurements) -> np.ndarray:
    """Upper band storage ``(BANDWIDTH + 1, 3 n_coef)`` of ``sum A_a' A_a``."""
    return band_of_rows(obs.j0, obs.attitude_rows().reshape(obs.size, _AX * _NB), obs.n_coef)


def band_to_dense(ab) -> np.ndarray:
    """Dense symmetric matrix from upper band storage (for tests and small problems)."""
    u, n = ab.shape[0] - 1, ab.shape[1]
    N = np.zeros((n, n))
    for d in range(u + 1):
        i = np.arange(n - d)
        N[i, i + d] = ab[u - d, d:]
        N[i + d, i] = ab[u - d, d:]
    return N


def free_coefficients(ab) -> np.ndarray:
    """(n_coef, 3) bool: coefficients with at least one measurement in their support."""
    return (ab[-1] > 0).reshape(-1, _AX)
