"""Simulated normalised measurements ``h`` of Eq. 1.

The true position offset at the reference epoch is zero, so the true parameter vector
of a star is ``x_true = (0, 0, parallax, pmra, pmdec)`` and the noiseless measurements
are ``A x_true``: the displacements produced by the true parallax and proper motion,
divided by the measurement uncertainty (Sect. 2.2). Adding independent standard normal
noise then models observation errors with exactly the formal uncertainties (the
"clean data set" of Sect. 2.2).
"""

from __future__ import annotations

import numpy as np

from ..errors import UserInputError

__all__ = ["simulate"]


def simulate(A, x_true, rng, mask=None) -> np.ndarray:
    """Normalised residuals ``h = A x_true + N(0, 1)``, zero on absent rows.

    Parameters
    ----------
    A : array_like, shape (n, m, 5)
        Normalised design matrix (:func:`mcsweep.astrometry.design.design_matrix`).
    x_true : array_like, shape (n, 5) or (5,)
        True parameters (mas, mas, mas, mas/yr, mas/yr).
    rng : numpy.random.Generator or int or numpy.random.SeedSequence
        Source of the noise; an int or SeedSequence seeds a new PCG64 generator.
        None is refused, so every simulation is reproducible.
    mask : array_like of bool, shape (n, k), optional
        True where the transit exists, with ``m = k`` or ``m = 2 k`` (AL then AC rows).
        Default: a row is absent when all its elements in ``A`` are zero.

    Returns
    -------
    h : ndarray, shape (n, m)
        Star-last memory layout, like ``A``. The normal draws fill an ``(m, n)``
        array, so for a given generator state the result is reproducible.
    """
    if rng is None:
        raise UserInputError("rng=None is not accepted; pass a numpy.random.Generator or an integer seed")
    rng = np.random.default_rng(rng)
    A = np.asarray(A, dtype=float)
    if A.ndim != 3 or A.shape[2] != 5:
        raise ValueError(f"A must have shape (n, m, 5), got {A.shape}")
    n, m, _ = A.shape
    x = np.broadcast_to(np.asarray(x_true, dtype=float), (n, 5))

    At = A.transpose(2, 1, 0)  # (5, m, n), contiguous for star-last input
    h = rng.standard_normal((m, n))
    for c in range(5):
        h += At[c] * x[:, c]
    if mask is None:
        present = np.any(At != 0.0, axis=0)
    else:
        mask = np.asarray(mask, dtype=bool)
        if mask.ndim != 2 or mask.shape[0] != n or m not in (mask.shape[1], 2 * mask.shape[1]):
            raise ValueError(f"mask shape {mask.shape} does not match A shape {A.shape}")
        present = mask.T if m == mask.shape[1] else np.concatenate([mask.T, mask.T], axis=0)
    h[~present] = 0.0
    return h.T
