"""The source block of AGIS: per-star 5 x 5 normal equations with the Eq. 18 prior.

With the attitude given, every star is solved on its own (Lindegren et al. 2012,
Sect. 5.2; the paper's Eqs. 11-13 with ``N_p`` of Eq. 18). The blocks are accumulated
from the flat observations with :func:`numpy.bincount` (one pass per matrix element,
no loop over stars) and solved with the batched Cholesky of
:func:`mcsweep.astrometry.linalg.spd_solve`. The inverse of a block is the star's
formal covariance with the attitude taken as known, as AGIS reports it.
"""

from __future__ import annotations

import numpy as np

from ..astrometry.linalg import spd_solve
from .observations import Measurements

__all__ = ["source_normals", "solve_sources"]

_NP = 5


def source_normals(obs: Measurements) -> np.ndarray:
    """Data part of every star's normal matrix, ``sum A_s' A_s`` (n, 5, 5)."""
    n = obs.n_stars
    N = np.empty((n, _NP, _NP))
    for i in range(_NP):
        for j in range(i + 1):
            N[:, i, j] = np.bincount(obs.star, obs.src[:, i] * obs.src[:, j], minlength=n)
            N[:, j, i] = N[:, i, j]
    return N


def solve_sources(N, b, prior_diagonal):
    """``x = (N + N_p)^-1 b`` and ``C = (N + N_p)^-1`` for every star.

    Parameters
    ----------
    N : ndarray (n, 5, 5)
    b : ndarray (n, 5)
    prior_diagonal : ndarray (5,) or (n, 5)
        Diagonal of ``N_p`` (Eq. 18), e.g. from :func:`mcsweep.astrometry.solve.prior_diagonal`.

    Returns
    -------
    x : ndarray (n, 5)
    cov : ndarray (n, 5, 5)
    ok : ndarray (n,) bool
        False where the block is numerically singular.
    """
    x, cov, ok, _ = spd_solve(N, b, add_diagonal=prior_diagonal)
    return x, cov, ok
