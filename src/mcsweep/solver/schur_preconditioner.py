"""The attitude block of the PCG preconditioner: the banded Schur complement and its factor.

The preconditioner is the block LDL' factorisation of ``N`` (symmetric block Gauss-Seidel
over the source and attitude blocks of AGIS, Lindegren et al. 2012, A&A 538, A78; PCG on
the full system as Bombrun et al. 2012, A&A 538, A77) with the attitude Schur complement
``S = N_aa - N_as B^-1 N_sa`` (``B = N_ss + N_p``, per star) replaced by its banded part:
``N_aa`` (:func:`~mcsweep.solver.blocks.att_band`, once per problem) minus each star's
absorption within one spline window (:func:`~mcsweep.solver.blocks.schur_absorption`, once
per prior), factorised once by LAPACK's banded Cholesky (``dpbtrf``, what
:func:`scipy.linalg.cholesky_banded` calls):

    z_a = S_band^-1 (r_a - N_as B^-1 r_s),   z_s = B^-1 (r_s - N_sa z_a).

A star seen at one or two epochs absorbs the attitude signal at those epochs, which
``N_aa`` counts as attitude information and ``S`` does not; the banded Schur block removes
that (iteration counts against block Jacobi: docs/solver_design.md, "Frame and preconditioner").

The absorption is summed slab by slab of the band's columns (:data:`SETUP_SLAB_BYTES`), each
slab's sum over the chunks going straight into the band: summed whole, each worker would
hold several bands at once (a block's, its leaf's and the tree's partial sums) at AGIS's
30 s knots. Every element is the same sum in the same order either way.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import LinAlgError, cho_solve_banded
from scipy.linalg.lapack import dpbtrf

from . import blocks as B
from .reduction import share_bounds
from .tasks import absorption_task, add_in_place

__all__ = ["SchurPreconditioner", "AttitudeNotDetermined", "schur_band", "band_factor", "SETUP_SLAB_BYTES"]

#: Bytes of the banded Schur block summed at once in the setup pass (:func:`schur_band`):
#: the band is summed in that many slabs of its columns, so no process holds more than the
#: driver's one band beyond slabs of this size (one slab below 32 MiB: every problem with
#: fewer than ~3.5e5 attitude unknowns, e.g. 3 h knots at the paper's sizes).
SETUP_SLAB_BYTES = 1 << 25


class AttitudeNotDetermined(LinAlgError):
    """The attitude block of the normal equations is singular: some attitude coefficient is
    not determined by the data (knots closer than the stars' transits can fix; more unknowns
    than measurements in its support). ``coefficient``, ``axis``: the first one found (the
    factorisation's first non-positive pivot)."""

    def __init__(self, coefficient: int, axis: int):
        super().__init__(f"attitude coefficient {coefficient} (axis {axis}) is not determined by the data")
        self.coefficient, self.axis = int(coefficient), int(axis)


def schur_band(pb, passes) -> np.ndarray:
    """The banded Schur block of problem ``pb`` in LAPACK upper storage: ``N_aa`` less the
    stars' absorption summed over the chunks of ``passes``
    (:class:`~mcsweep.solver.executors.ChunkPasses`, after the setup pass), slab by slab of
    its columns; coefficients without data held at zero by identity rows. The driver
    receives one slab per chunk before summing them in the fixed order (a few per worker
    with forked workers; with many small Dask chunks, many)."""
    n_att = 3 * pb.n_coef
    cuts = share_bounds(n_att, -(-8 * (B.schur_bandwidth() + 1) * n_att // SETUP_SLAB_BYTES))
    band = None
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        (part,) = passes.summed(absorption_task, [(i, (lo, hi), passes.leaves[i]) for i in passes.n_ch],
                                [("leaves", add_in_place)], fresh=False)
        if band is None:
            band = np.empty((part.shape[0], n_att))
        np.negative(part, out=band[:, lo:hi])
        del part
    band[-pb.naa_band.shape[0]:] += pb.naa_band
    fixed = ~pb.free.ravel()
    band[:, fixed] = 0.0
    band[-1, fixed] = 1.0
    return band


def band_factor(band, naa_band) -> np.ndarray:
    """The Cholesky factor of ``band`` (overwritten where a ridge is needed) by LAPACK's
    banded Cholesky, whose info is the first non-positive leading minor: the unknown named
    by :class:`AttitudeNotDetermined` if the attitude is not determined. A failure from
    rounding in an attitude window no well-observed star constrains is met by a tiny ridge
    (``1e-12`` of ``N_aa``'s diagonal)."""
    chol, info = dpbtrf(np.asarray_chkfinite(band), lower=0)
    if info > 0:  # rounding in an attitude window no well-observed star constrains: a tiny ridge
        band[-1] += 1e-12 * np.maximum(naa_band[-1], 1.0)
        chol, info = dpbtrf(band, lower=0)
        if info > 0:  # not rounding: the data leave attitude unknowns free
            raise AttitudeNotDetermined((info - 1) // 3, (info - 1) % 3)
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of the banded Cholesky factorisation")
    return chol


class SchurPreconditioner:
    """The attitude step of the preconditioner for problem ``pb``: the banded Schur block
    summed over the chunks of ``passes`` and factorised once (only the factor is kept)."""

    def __init__(self, pb, passes):
        self.free = pb.free
        self.chol = band_factor(schur_band(pb, passes), pb.naa_band)

    def attitude_step(self, r_a, w_a) -> np.ndarray:
        """``z_a = S_band^-1 (r_a - w_a)`` (``w_a = N_as B^-1 r_s``, the first sweep's attitude
        part), zero for the coefficients without data."""
        w_a = np.where(self.free, r_a - w_a, 0.0)
        # chol is finite (dpbtrf succeeded on a checked band) and w_a is a sum of the passes: no
        # finiteness scan of the 12 x 2.3e6 factor every iteration (7 % of the driver's time at
        # AGIS's knots, py-spy)
        return np.where(self.free,
                        cho_solve_banded((self.chol, False), w_a.ravel(), check_finite=False).reshape(-1, 3), 0.0)
