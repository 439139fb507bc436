"""Normal equations of the global solution and their preconditioned conjugate-gradient solution.

Unknowns: the five astrometric parameters of ``n`` stars (Eq. 1 order, mas and mas/yr)
and the attitude spline coefficients (``n_coef x 3``, mas). The normal matrix

    N = [[N_ss + N_p + F, N_sa], [N_as, N_aa]]

(``N_p`` the prior of Eq. 18, ``F`` the frame penalty of :mod:`mcsweep.solver.frame`)
is never formed.

Method: PCG on the full system (Bombrun et al. 2012, A&A 538, A77) with a symmetric
block Gauss-Seidel preconditioner, the block LDL' factorisation of ``N`` with the
attitude Schur complement ``S = N_aa - N_as B^-1 N_sa`` (``B = N_ss + N_p``, per star)
replaced by its banded part, ``N_aa`` (:func:`~mcsweep.solver.blocks.att_band`, once per
problem) minus each star's absorption within one spline window
(:func:`~mcsweep.solver.blocks._schur_absorption`, once per prior), factorised once with
:func:`scipy.linalg.cholesky_banded`:

    z_a = S_band^-1 (r_a - N_as B^-1 r_s),   z_s = B^-1 (r_s - N_sa z_a).

The operator ``N`` itself is applied exactly (an elimination of the stars inside the
operator would be ruined by rounding: a star seen once under a 1000 mas prior has a
5 x 5 block of condition ~1e10).

What fixed the 1000 mas failure, measured on an experiment-like problem (3000 stars,
one year, 20 % dead time, 1000 mas prior; direct solve for reference):

* Frame. The zero-rotation and zero-spin constraint now weights every star by its
  formal precision (:attr:`GlobalProblem.frame_weights`). With equal weights a loose
  prior lets the constraint be met by the stars whose proper motions the data leave
  free (1-2 transits, sigma_mu = R x 1000 mas/yr), so the spin of the well-observed
  stars and of the attitude is left to the 1e-8 weight of their priors: a near-null
  space. Block-Jacobi PCG (``diag(B, N_aa)``, AGIS's S and A blocks side by side, the
  solver before) then stopped at rtol 1e-8 after 823 iterations with positions
  385 mas from the direct solution (2461 iterations at 1e-12, still 53 uas off).
* Preconditioner. A star seen at one or two epochs absorbs the attitude signal at
  those epochs, which ``N_aa`` counts as attitude information and ``S`` does not;
  the banded Schur block removes that. With the weighted frame, on the benchmark
  problem (benchmarks/bench_primary.py, 1933 stars, one year, a quarter of the
  transits kept): 22 / 38 / 39 / 46 iterations for priors 0.01 / 1 / 10 / 1000 mas
  against 51 / 123 / 131 / 138 for block Jacobi; on the problem above 31.

Each iteration is two passes over the measurements in blocks of stars (the two
sweeps of the preconditioner; ``N z`` is formed in the second, ``N p`` by recursion,
``q = N z + beta q``): chunk tasks of :mod:`~mcsweep.solver.blocks` summed in the fixed
order of :mod:`~mcsweep.solver.reduction`, so the solution is bit-identical for any
chunking, backend and number of workers. The two attitude vectors of a pass are summed per
leaf of blocks (reduction, "Leaves"): with AGIS's 30 s knots each block would otherwise
zero, send and add a vector of 2.3e6 unknowns for its 8e5 measurements.

Where the vectors live. Every star vector of the iteration (right-hand side, solution,
residual, search direction, ``N p``, the preconditioned residual and the prior-and-frame
parts kept for the residual RMS) is held chunk by chunk where the chunk's measurements
are (in-process, a forked worker of :mod:`~mcsweep.solver.resident`, or a Dask worker of
:mod:`~mcsweep.solver.dask_resident`), and updated there. The driver holds the attitude
vectors and the banded Schur factor; an iteration exchanges with each chunk the step
``alpha``, the attitude vector ``z_a``, the six frame sums and ``beta`` one way, and two
attitude-sized vectors and a few per-block sums (dot products, convergence numbers) the
other, in three rounds (forward sweep with the step, back sweep, new direction); on a Dask
cluster each worker first adds its chunks' vectors and sums where the fixed tree adds them
(``reduced``, :meth:`~mcsweep.solver.dask_resident.DaskChunks.reduced`), so the driver gets a
few per worker. The star vectors reach the driver once, as the solution. Before (issue 27), the driver held them and
sent each chunk's share of two of them every pass: 64 MiB per iteration at the paper's
1.5e6 stars. A :class:`ResidentProblem` goes further: the per-star arrays of the problem
itself (prior, inverses, frame weights) are made where the chunk is (:func:`star_arrays`)
and the solution stays there, so the driver holds nothing per star. Dot products are now sums of per-block dots in the fixed tree, so the
rounding differs from a single dot over the whole vector (the same for every backend).

Bordered unknowns. A few unknowns that every measurement may depend on (a calibration,
:mod:`~mcsweep.solver.calibration`; partials ``C (m, k)``, no prior, no frame) border the
system: ``[[N, G], [G', D]]`` with ``G = A'C``, ``D = C'C``. ``G`` is made once, in the setup
pass, as the right-hand side each column would give as measurements; its stars' rows stay
with their chunks (``k`` star vectors more there), its attitude rows on the driver. An
iteration then needs no further pass over the measurements: the chunks add ``G_s z_c`` to
``N z`` and return ``G_s' z_s`` with their dots, the driver does the rest, and the
preconditioner takes the bordered unknowns by ``D^-1`` (block diagonal). The preconditioned
matrix so differs from the unbordered one by rank ``<= 2k``, which costs CG at most ``2k``
more iterations in exact arithmetic, however nearly degenerate the bordered unknowns are
with the rest (the basic-angle variation with the parallax zero point).

Starting attitude. ``attitude_start = a0`` starts PCG from ``x0 = (0, a0)``: each chunk's
setup takes ``h - A_a a0`` for its measurements (one more spline product per measurement,
once), so the iteration solves for the correction from ``x0``, and the solution is ``a0`` plus
it (the bordered unknowns' right-hand side loses ``G_a' a0``). The energy criterion bounds the
error of the whole solution as before; the relative residual of the other rule is then
``|b - N x| / |b - N x0|``, relative to the starting residual.
The stars need no start of their own: the first preconditioner step gives them their update
given the attitude, ``B^-1 (r_s - N_sa z_a)``. Any start gives the least-squares solution to
``error_tol``; a start near it removes most of the error the slow modes (the weakly determined
knots) would otherwise carry from zero. Measured on the primary experiment at 25 FoV
transits per knot, each prior started from the attitude of the prior before it (sigma_F90,
then 10 sigma_F90): 10 sigma_F90 and 1000 mas in 158 / 180 iterations instead of 222 / 276 (3 x 10000
stars), 516 / 682 instead of 663 / 871 (3 x 30000); starting sigma_F90 from a 3 h knot
solution's attitude gave 95 instead of 120 (3 x 10000, not kept: a second problem to build).
The slow modes stay slow: a start shrinks the error they hold, not their number. The error
estimate of the energy criterion (below) leaves out the first step of a started solution:
that step also moves the stars from zero to their update, orders of magnitude more than the
steps after it, and a window that began with it extrapolated a decay far too fast (measured:
at 3 h knots 1000 mas from 10 sigma_F90's attitude stopped at iteration 11 with an actual
error of 0.0145 against the 0.01 asked, the estimate 2.3 times too small even with the
safety factor; at 25 FoV transits per knot the estimate at iteration 11 was 5.5 times too
small; from iteration 12 on, the first without that step in its window, at most 1.02 times
too small wherever it was below 1, i.e. 2.55 before the safety factor, against 2.03 from zero).

Convergence criterion (stated for users). By default (``error_tol`` given, as the
experiments do) PCG stops when the error of the solution, measured in the norm of the
normal matrix, ``|x - x*|_N = sqrt((x - x*)' N (x - x*))``, is estimated to be below
``error_tol``. Why this norm: for any linear function ``g'x`` of the unknowns (a star's
position, an attitude coefficient, a frame-free combination), Cauchy-Schwarz gives
``|g'(x - x*)| <= sqrt(g' N^-1 g) |x - x*|_N``, and ``sqrt(g' N^-1 g)`` is the formal
standard error of ``g'x``. So ``error_tol = 0.01`` means that no estimated quantity is off
the exact least-squares solution by more than 1 % of its own formal uncertainty, whether it
is a bright star's position known to 10 uas or the in-plane attitude at a 30 s knot seen
only by faint stars, known to a few mas; and ``|x - x*|_N^2`` is the chi-square the
truncation adds. An absolute update tolerance (below) treats those two alike, and at AGIS's
knots the weak knots' updates kept it unmet for 1000 iterations after the stars had stopped
moving (docs/table3.md).

The estimate. The steps of CG are N-orthogonal, so the squared error of iterate ``x_k`` is
the sum of the squared N-norms of all later steps, ``|x* - x_k|_N^2 = sum_{i > k} s_i`` with
``s_i = alpha_i r_{i-1}' z_{i-1}`` (Hestenes & Stiefel 1952, J. Res. NBS 49, 409; Strakos &
Tichy 2002, ETNA 13, 56, show that this holds in finite precision too). The sum of the next
few steps would only be known that many iterations later (20 iterations more at 3 h knots,
where 39 suffice); instead the remaining sum is extrapolated from the last ``ERROR_WINDOW``
steps as a geometric series, ``s_k q / (1 - q)`` with ``q = (s_k / s_{k-w})^(1/w)`` (infinite
while the steps do not fall), and multiplied by ``ERROR_SAFETY``. Measured on the primary
experiment, against the error of every iterate from the sum of the steps to a relative
residual of 1e-10: at 3 h knots (3 x 30000 stars) and at 25 FoV transits per knot (3 x 10000),
three priors each, the unscaled extrapolation was at most 2.03 times too small wherever it was
below 1 (2.37 from 5 steps, 1.71 from 20); with the factor, ``error_tol = 0.01`` stopped at iterations 39 / 39 / 39 and 122 /
222 / 278 (sigma_F90 / 10 sigma_F90 / 1000 mas) with actual errors of 0.0022-0.0043 (the
relative-residual rule below: 43 / 47 / 51 and 160 / 297 / 381). Checked against a direct
solve in ``tests/solver/test_energy_criterion.py``.

Otherwise (``error_tol=None``) it stops after iteration ``k >= min_iter`` when both

* the relative residual of the normal equations ``|b - N x| / |b| < rtol``
  (recursively updated; from a starting attitude ``|b - N x| / |b - N x0|``), and
* the largest change of any unknown in that iteration (attitude coefficients and all
  five parameters of every star, mas or mas/yr) is below ``update_tol_uas``
  microarcseconds;

Either way it stops after ``max_iter`` iterations (then ``converged = False``). Every
iteration is logged (update norms in microarcsec, RMS of the normalised residuals, relative
residual, the step's squared N-norm and the error estimate).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from functools import partial
from typing import Callable, Iterable, Iterator

import numpy as np
from scipy.linalg import LinAlgError, cho_solve_banded
from scipy.linalg.lapack import dpbtrf

from ..astrometry.design import tangent_triad
from . import blocks as B
from . import kernels
from .attitude_update import free_coefficients
from .frame import precision_weights, rotation_matrices
from .observations import Observations
from .reduction import chunk_ranges, leaf_blocks, pairwise_sum, run_level, share_bounds, share_of
from .resident import forked_chunks
from .source_update import solve_sources, source_normals

__all__ = ["GlobalProblem", "ResidentProblem", "ConvergenceRecord", "GlobalSolution", "solve_global", "make_blocks", "in_block_order",
           "UAS_PER_MAS",
           "BLOCK_STARS", "ERROR_WINDOW", "ERROR_SAFETY", "ChunksLost", "AttitudeNotDetermined", "solver_chunks"]

UAS_PER_MAS = 1000.0
#: Stars per reduction block (module notes of :mod:`~mcsweep.solver.reduction`). Every
#: block adds one attitude-sized vector per pass; where a block holds fewer measurements
#: than there are attitude unknowns (AGIS's 30 s knots), blocks are summed in leaves
#: (:func:`~mcsweep.solver.reduction.leaf_blocks`) so that this overhead stays small.
BLOCK_STARS = 32768
#: Steps whose mean decrease extrapolates the error of the energy criterion (module notes).
ERROR_WINDOW = 10
#: Factor on the extrapolated error: the largest under-estimate measured from 10 steps, 2.03,
#: with a margin (module notes).
ERROR_SAFETY = 2.5


@dataclasses.dataclass
class ConvergenceRecord:
    """One iteration: update norms [microarcsec], residual RMS, relative residual, wall time;
    ``energy_decrease`` the step's squared N-norm (``alpha r'z``), ``error_estimate`` the
    estimated ``|x* - x|_N`` after it (NaN for the first ``ERROR_WINDOW`` iterations and
    without ``error_tol``; module notes)."""

    iteration: int
    update_max_uas: float
    update_rms_position_uas: float
    update_rms_attitude_uas: float
    residual_rms: float
    relative_residual: float
    seconds: float
    energy_decrease: float = float("nan")
    error_estimate: float = float("nan")


@dataclasses.dataclass
class GlobalSolution:
    """Result of :func:`solve_global`."""

    x: np.ndarray            # (n, 5) stars
    attitude: np.ndarray     # (n_coef, 3) spline coefficients [mas]
    cov: np.ndarray          # (n, 5, 5) per-star covariance, attitude as known (the problem's; read only)
    residuals: np.ndarray | None  # (m,) normalised measurement residuals h - A x (None unless asked)
    residual_rms: float      # RMS of the normalised residuals (from the explicit final pass)
    history: list
    converged: bool
    border: np.ndarray | None = None  # (k,) the bordering unknowns (solve_global's ``border``), if any


def make_blocks(obs: Observations, ra_deg, dec_deg, *, block_stars: int = BLOCK_STARS, compact: bool = False,
                first_star: int = 0) -> list:
    """The :class:`~mcsweep.solver.blocks.StarBlock` s of ``obs`` (without per-star inverses).

    ``ra_deg, dec_deg`` (``obs.n_stars``,): directions of ``obs``'s stars. ``rows`` index
    ``obs``'s measurements. ``obs`` may hold a part of the problem: its stars are
    ``first_star + obs.star`` (``first_star`` a multiple of ``block_stars``); the parts'
    blocks are then put in one observation order by :func:`in_block_order`. A problem
    built part by part (:meth:`GlobalProblem.from_blocks`) never holds all measurements'
    partials twice: each part's :class:`Observations` can be dropped once its blocks are made.
    """
    if first_star % block_stars:
        raise ValueError(f"first_star={first_star} is not a multiple of block_stars={block_stars}")
    order = np.argsort(obs.star, kind="stable")
    star_sorted = obs.star[order]
    real = np.float32 if compact else np.float64
    star_int = np.int16 if block_stars <= np.iinfo(np.int16).max + 1 else np.int32
    p, q, _ = tangent_triad(np.asarray(ra_deg, dtype=float), np.asarray(dec_deg, dtype=float))
    pq = np.column_stack([p, q])  # (n, 6)
    out = []
    for first in range(0, obs.n_stars, block_stars):
        last = min(first + block_stars, obs.n_stars)
        lo, hi = np.searchsorted(star_sorted, [first, last])
        rows = order[lo:hi]
        rows = rows[np.argsort(obs.j0[rows], kind="stable")]  # time order within the block (StarBlock)
        j0 = obs.j0[rows]
        seg = np.flatnonzero(np.r_[True, j0[1:] != j0[:-1]]) if j0.size else np.zeros(0, np.int64)
        out.append(B.StarBlock(first=first_star + first, n=last - first,
                               rows=rows.astype(np.int32 if obs.size < 2**31 else np.int64),
                               star=(obs.star[rows] - first).astype(star_int),
                               src=np.ascontiguousarray(obs.src[rows, :3].T, dtype=np.float64),
                               t=obs.t_yr[rows], pq=np.ascontiguousarray(pq[first:last]),
                               j0=j0.astype(np.int32), bval=np.ascontiguousarray(obs.bval[rows].T, dtype=real),
                               binv=None, n_coef=obs.n_coef, seg=seg, seg_j0=j0[seg].astype(np.int64)))
    return out


def in_block_order(blocks: list, first_row: int) -> list:
    """The same blocks, their measurements numbered in block order from ``first_row``.

    Block ``k`` then holds the contiguous rows ``slice(start_k, start_k + m_k)``: no index
    array is stored, and the solver reads each block's measurements as a view instead of
    a copy. The caller stores its per-measurement arrays (the measurements ``h``) in the
    blocks' own order.
    """
    out, start = [], first_row
    for b in blocks:
        m = int(np.size(b.rows))
        out.append(dataclasses.replace(b, rows=slice(start, start + m)))
        start += m
    return out


class GlobalProblem:
    """The normal equations of one global solution, in blocks of stars.

    Parameters
    ----------
    obs : Observations
        Every star must be determinable on its own with the prior (check with
        :func:`~mcsweep.solver.source_update.solve_sources` first). The problem keeps
        the partials in its blocks, not ``obs``; its observation order is ``obs``'s.
        For problems too large to hold all partials twice build it part by part with
        :func:`make_blocks` and :meth:`from_blocks`.
    prior_diagonal : array_like (5,) or (n, 5)
        Diagonal of ``N_p`` (Eq. 18).
    ra_deg, dec_deg : array_like (n,)
        Star directions (for the frame constraint).
    block_stars : int, keyword-only
        Stars per reduction block (:data:`BLOCK_STARS`); part of the problem, not of the
        execution: the rounding of the sums depends on it, not on the chunking.
    compact : bool, keyword-only
        Store the spline values as float32 (54 instead of 70 bytes per measurement;
        products and sums stay float64). Off by default: rounded partials define another
        problem. Measured when the attitude partials were stored too (float32 both, on an
        experiment-like problem: 3000 stars, one year, 1000 mas): the solution moved by
        2.5e-6 relative to the float64 problem's direct solution (2.6e-5 of the formal
        sigma, 8 uas for a star with sigma ~ arcsec), over the 1e-6 asked of the solver;
        float32 source partials as well: 3.9e-4 (1.4e-3 sigma). The problem solved is the
        one with the stored partials (:meth:`design` gives them).
    """

    def __init__(self, obs: Observations, prior_diagonal, ra_deg, dec_deg, *, block_stars: int = BLOCK_STARS,
                 compact: bool = False):
        self._assemble(make_blocks(obs, ra_deg, dec_deg, block_stars=int(block_stars), compact=bool(compact)),
                       source_normals(obs), prior_diagonal, ra_deg, dec_deg, n_coef=obs.n_coef,
                       n_measurements=obs.size)

    @classmethod
    def from_blocks(cls, blocks, normals, prior_diagonal, ra_deg, dec_deg, *, n_coef: int,
                    n_measurements: int, naa_band=None) -> "GlobalProblem":
        """The problem from blocks made part by part (:func:`make_blocks`).

        ``blocks`` cover stars ``0 .. n - 1`` in order with one block size, their rows
        ``0 .. n_measurements - 1`` (the observation order); ``normals`` (n, 5, 5) the
        stars' data normal matrices (:func:`~mcsweep.solver.source_update.source_normals`
        of the parts, concatenated). Blocks kept on a cluster's workers are given as
        :class:`~mcsweep.solver.blocks.BlockSpan` s with ``naa_band``, the sum of their
        :func:`~mcsweep.solver.blocks.att_band` in the fixed tree; the problem then solves
        with their resident chunks only (:func:`solve_global`'s ``resident_chunks``).
        """
        blocks = list(blocks)
        firsts = [b.first for b in blocks]
        sizes = {b.n for b in blocks[:-1]}
        if firsts != [i * blocks[0].n for i in range(len(blocks))] or len(sizes) > 1 or \
                sum(b.n for b in blocks) != len(normals):
            raise ValueError("blocks must cover the stars in order with one block size")
        self = cls.__new__(cls)
        if naa_band is None and any(isinstance(b, B.BlockSpan) for b in blocks):
            raise ValueError("blocks kept elsewhere (BlockSpan) need their naa_band")
        self._assemble(blocks, np.asarray(normals, dtype=float), prior_diagonal, ra_deg, dec_deg,
                       n_coef=int(n_coef), n_measurements=int(n_measurements), naa_band=naa_band)
        return self

    def _assemble(self, blocks, normals, prior_diagonal, ra_deg, dec_deg, *, n_coef, n_measurements,
                  naa_band=None):
        self.n_stars = n = len(normals)
        self.n_coef = n_coef
        self.n_measurements = n_measurements
        self.N_src = normals
        self.K = rotation_matrices(ra_deg, dec_deg)
        self.blocks = blocks
        self._set_prior(prior_diagonal)
        self.n_src = 5 * n
        self.n_att = 3 * n_coef
        self.size = self.n_src + self.n_att
        # Coefficients whose support holds no measurement (inside dead time) are held at
        # zero (identity rows), as AGIS breaks the attitude into segments at data gaps.
        self.naa_band = pairwise_sum(B.att_band(b) for b in self.blocks) if naa_band is None else naa_band
        self.free = free_coefficients(self.naa_band)

    def _set_prior(self, prior_diagonal):
        n, N_src = self.n_stars, self.N_src
        self.prior = np.broadcast_to(np.asarray(prior_diagonal, dtype=float), (n, 5))
        _, self.src_inv, ok = solve_sources(N_src, np.zeros((n, 5)), self.prior)
        if not ok.all():
            raise ValueError(f"{int((~ok).sum())} stars have singular source blocks; remove them first")
        self.blocks = [dataclasses.replace(b, binv=self.src_inv[b.first:b.first + b.n]) for b in self.blocks]
        # Frame constraint weights (module notes, "Frame"): each star's formal precision of
        # position and proper motion (attitude as known), normalised to mean 1.
        g = precision_weights(self.src_inv)
        self.frame_means = pairwise_sum(weight_sums(g[b.first:b.first + b.n]) for b in self.blocks) / max(n, 1)
        self.frame_weights = normalised_weights(g, self.frame_means)
        self.w_pos, self.w_pm = penalty_weights(*map(np.median, typical_weights(N_src, self.prior)), n)

    @property
    def stars_with_chunks(self) -> bool:
        """Whether the per-star arrays live with the chunks (:class:`ResidentProblem`)."""
        return False

    def with_prior(self, prior_diagonal) -> "GlobalProblem":
        """The same measurements under another prior, sharing the stored partials (the
        per-star inverses and frame weights are new): one problem serves every prior of
        Table 3."""
        new = copy.copy(self)
        new._set_prior(prior_diagonal)
        return new

    # ------------------------------------------------------------ layout
    def split(self, v):
        """(stars (n, 5), attitude (n_coef, 3)) views of a full vector."""
        return v[:self.n_src].reshape(-1, 5), v[self.n_src:].reshape(-1, 3)

    def join(self, xs, xa) -> np.ndarray:
        return np.concatenate([np.ravel(xs), np.ravel(xa)])

    # ------------------------------------------------------------ products (tests, diagnostics)
    def forward(self, v) -> np.ndarray:
        """``A v`` (m,) in observation order: normalised measurement change for unknowns ``v``."""
        xs, xa = self.split(v)
        out = np.empty(self.n_measurements)
        for b in self.blocks:
            out[b.rows] = B.src_forward(b, xs[b.first:b.first + b.n]) + B.att_forward(b, xa)
        return out

    def frame_penalty(self, xs) -> np.ndarray:
        """``F x`` (n, 5): the penalty of the weighted zero-mean rotation and spin constraint
        (compiled passes over the stars, :func:`~mcsweep.solver.kernels.frame_sums` per
        block summed in the fixed tree, then :func:`~mcsweep.solver.kernels.frame_apply`,
        as the solver does)."""
        K, g = self.K, self.frame_weights
        sums = pairwise_sum(kernels.frame_sums(K[b.first:b.first + b.n], g[b.first:b.first + b.n],
                                               xs[b.first:b.first + b.n]) for b in self.blocks)
        return kernels.frame_apply(K, g, np.zeros(6) if sums is None else sums, self.w_pos, self.w_pm,
                                   np.zeros((self.n_stars, 5)))

    def apply(self, v) -> np.ndarray:
        """``N v`` of the full system (unobserved attitude coefficients: identity rows)."""
        xs, xa = self.split(v)
        parts = [B.block_normal_apply(b, xs[b.first:b.first + b.n], xa) for b in self.blocks]
        ys = np.concatenate([p[0] for p in parts]) + self.prior * xs + self.frame_penalty(xs)
        ya = pairwise_sum(p[1] for p in parts)
        ya[~self.free] = xa[~self.free]
        return self.join(ys, ya)

    def design(self):
        """The stored partials in observation order as float64: (star (m,), src (m, 5), att (m, 3),
        j0 (m,), bval (m, 4)) (tests and direct solutions)."""
        m = self.n_measurements
        star, j0 = np.empty(m, np.int64), np.empty(m, np.int64)
        src, att, bval = np.empty((m, 5)), np.empty((m, 3)), np.empty((m, 4))
        for b in self.blocks:
            # int64 before the offset: a block's int16 indices plus a first star >= 32768 overflow
            star[b.rows], j0[b.rows] = b.star.astype(np.int64) + b.first, b.j0
            src[b.rows], att[b.rows], bval[b.rows] = B.src_rows(b).T, B.att_rows(b).T, b.bval.T
        return star, src, att, j0, bval

    @property
    def nbytes_per_measurement(self) -> float:
        """Bytes held per measurement by the blocks (partials, indices, per-star inverses)."""
        return sum(b.nbytes for b in self.blocks) / max(self.n_measurements, 1)

    def chunks(self, chunk_stars: int | None, shares: int = 1) -> list[tuple[int, int]]:
        """Block ranges of the execution chunks (:func:`solver_chunks`)."""
        return solver_chunks(len(self.blocks), self.blocks[0].n if self.blocks else 1, self.n_measurements,
                             self.n_coef, chunk_stars, shares)

    @property
    def leaf(self) -> int:
        """Blocks per leaf (:func:`~mcsweep.solver.reduction.leaf_blocks`)."""
        return leaf_blocks(len(self.blocks), self.n_measurements, 3 * self.n_coef)


def solver_chunks(n_blocks: int, block_stars: int, n_measurements: int, n_coef: int, chunk_stars: int | None,
                  shares: int = 1) -> list[tuple[int, int]]:
    """Block ranges of the execution chunks of a problem of ``n_blocks`` blocks of ``block_stars``
    stars, ``n_measurements`` measurements and ``n_coef`` spline coefficients per axis: aligned
    runs of whole leaves of at most ``chunk_stars`` stars (None: as long as they go) within
    ``shares`` equal shares (:func:`~mcsweep.solver.reduction.chunk_ranges`). Chunks kept on a
    cluster must be these (:meth:`GlobalProblem.chunks`, whose rule this is)."""
    return chunk_ranges(n_blocks, None if chunk_stars is None else max(1, int(chunk_stars) // block_stars),
                        shares=shares, leaf=leaf_blocks(n_blocks, n_measurements, 3 * n_coef))



def weight_sums(g) -> np.ndarray:
    """Column sums (2,) of one block's frame weights ``g (n, 2)`` (summed over blocks in the
    fixed tree, so the means are the same bits wherever the blocks are)."""
    return np.array([np.sum(g[:, 0]), np.sum(g[:, 1])])


def normalised_weights(g, means) -> np.ndarray:
    """Frame constraint weights (module notes, "Frame"): each star's formal precision of
    position and proper motion (attitude as known), normalised to mean 1."""
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


def star_arrays(blocks, normals, prior) -> dict:
    """What a chunk's stars need for one prior, made where the chunk is: the prior diagonal,
    the inverses ``(N_ss + N_p)^-1`` (``ok`` False where singular), the rotation matrices of
    the frame (from the blocks' tangent directions) and the unnormalised frame weights."""
    _, binv, ok = solve_sources(normals, np.zeros((len(normals), 5)), prior)
    pq = np.concatenate([b.pq for b in blocks]) if blocks else np.zeros((0, 6))
    K = np.stack([pq[:, 3:6], -pq[:, 0:3]], axis=-2)  # frame.rotation_matrices from p, q
    prior = np.ascontiguousarray(np.broadcast_to(np.asarray(prior, dtype=float), (len(normals), 5)))
    return {"prior": prior, "binv": binv, "ok": ok, "K": K,
            "g_raw": precision_weights(binv)}


class ResidentProblem:
    """The driver's side of a problem whose blocks, measurements and per-star arrays (data
    normal matrices, prior, inverses, frame weights, solution) all stay with their chunks on
    a cluster's workers (:mod:`mcsweep.experiments.primary_cluster`): the block spans, the
    attitude band, the frame's means and penalty weights. :func:`solve_global` solves it
    with its ``resident_chunks`` only, and the stars' solution stays there too
    (``GlobalSolution.x`` and ``cov`` are None)."""

    prior = K = frame_weights = src_inv = None
    stars_with_chunks = True

    def __init__(self, spans, *, n_coef: int, n_measurements: int, naa_band, frame_means, w_pos: float,
                 w_pm: float):
        self.blocks = list(spans)
        self.n_stars = sum(b.n for b in self.blocks)
        self.n_coef, self.n_measurements = int(n_coef), int(n_measurements)
        self.naa_band = naa_band
        self.free = free_coefficients(naa_band)
        self.frame_means = np.asarray(frame_means, dtype=float)
        self.w_pos, self.w_pm = float(w_pos), float(w_pm)

    chunks = GlobalProblem.chunks
    leaf = GlobalProblem.leaf


# ---------------------------------------------------------------------- chunk tasks
# Every task's item starts (chunk index, blocks, measurements, state): what a worker keeps.
# ``state`` (a dict, filled by the setup task) holds the chunk's share of every star vector
# of the iteration (right-hand side, solution, residual, search direction, N p, ...), so a
# pass sends only attitude-sized vectors and a few numbers and gets the same back (module
# notes, "Where the vectors live"). Per-block numbers (dots, sums) are added in the fixed
# tree of mcsweep.solver.reduction, so no result depends on the chunking.

def _views(blocks, *vectors):
    """Per block, the block's rows of each chunk vector (n_chunk, 5)."""
    first = blocks[0].first
    return [[v[b.first - first:b.first - first + b.n] for v in vectors] for b in blocks]


def _leaf_runs(blocks, leaves):
    """Per leaf (``leaves``: local block ranges), its blocks as (index in the chunk, block, rows of
    a chunk star vector)."""
    first = blocks[0].first
    for lo, hi in leaves:
        yield [(k, b, slice(b.first - first, b.first - first + b.n)) for k, b in enumerate(blocks[lo:hi], lo)]


def _add_setup(a: dict, b: dict) -> dict:
    """Two partial sums of the setup pass, added into ``a``'s arrays where they are writable:
    the partials are the tree's own (nobody else holds them), and at AGIS's knots each holds
    attitude vectors of 2.3e6 unknowns, one fewer alive per level. Element by element, so the
    same bits as ``a + b``."""
    return {k: _add_in_place(a[k], b[k]) if isinstance(a[k], np.ndarray) else a[k] + b[k] for k in a}


def _setup_task(item):
    """Right-hand side and the chunk's star vectors. ``prior, K, g``: the chunk's arrays, or
    (stars kept with the chunk, ``st["stars"]``: :func:`star_arrays`) None, None and the
    frame weights' means."""
    ci, blocks, hs, st, prior, K, g, leaves, start = item
    b_s = np.empty((sum(b.n for b in blocks), 5))
    stars, cols = st.get("stars"), st.get("border")
    g_s = None if cols is None else np.empty((cols[0].shape[1], len(b_s), 5))
    if prior is None:
        prior, K, g = stars["prior"], stars["K"], normalised_weights(stars["g_raw"], g)

    def leaf_setup(run):
        """The leaf's sums, its blocks' added in block order (streamed, one block's alive at a
        time)."""
        acc = None
        for k, b, v in run:
            part = B.block_setup(b, hs[k], start)  # less what a starting attitude explains (module notes)
            b_s[v] = part.pop("b_s")
            part["bb"] = _dot(b_s[v], b_s[v])
            if cols is not None:  # G = A' C, the bordering columns' right-hand sides (module notes)
                g = B.gather(b)
                for j, col in enumerate(cols[k].T):
                    g_s[j, v] = B.src_adjoint(b, col, g)
                part["g_a"] = np.stack([B.att_adjoint(b, col, g) for col in cols[k].T])
            acc = part if acc is None else _add_setup(acc, part)
        return acc

    sums = pairwise_sum((leaf_setup(run) for run in _leaf_runs(blocks, leaves)), _add_setup)
    st.clear()
    if stars is not None:
        st["stars"] = stars
    if cols is not None:
        st["border"], st["g_s"] = cols, g_s
    zero = np.zeros_like(b_s)
    st.update(b=b_s, x=zero.copy(), r=b_s.copy(), e_x=zero.copy(), p=zero.copy(), q=zero.copy(), e_p=zero,
              prior=np.ascontiguousarray(prior, dtype=float), K=np.ascontiguousarray(K, dtype=float),
              g=np.ascontiguousarray(g, dtype=float))
    return ci, sums


def _absorption_task(item):
    """The chunk's part of the banded Schur block's absorption in the band's unknowns
    ``columns = (lo, hi)`` (one slab, :data:`SETUP_SLAB_BYTES`): its blocks' added per leaf in
    block order and the leaves in the fixed tree, as :func:`_setup_task` adds its sums.
    Needs the stars' prior that :func:`_setup_task` kept."""
    ci, blocks, _, st, columns, leaves = item
    prior = st["prior"]

    def leaf_absorption(run):
        acc = None
        for _, b, v in run:
            part = B._schur_absorption(b, prior[v], columns=columns)
            acc = part if acc is None else _add_in_place(acc, part)
        return acc

    return ci, pairwise_sum((leaf_absorption(run) for run in _leaf_runs(blocks, leaves)), _add_in_place)


def _add_in_place(a, b):
    """``a + b`` into ``a`` where it is writable (a partial sum of the tree's own)."""
    return np.add(a, b, out=a) if a.flags.writeable else a + b


def _forward_task(item):
    """Apply the step ``alpha`` (None: none yet) to x, r and (N_p + F) x; the chunk's shares of
    the convergence numbers; then the first sweep of the preconditioner on the new r."""
    ci, blocks, _, st, alpha, leaves = item
    if alpha is None:
        numbers, largest = np.zeros(4), 0.0
    else:
        step = alpha * st["p"]
        st["x"] += step
        st["e_x"] += alpha * st["e_p"]
        st["r"] -= alpha * st["q"]
        # x'(b + r), x'(N_p + F) x, sum of squared position steps, r'r
        numbers = pairwise_sum(np.array([_dot(x, b + r), _dot(x, e), _dot(d[:, :2], d[:, :2]), _dot(r, r)])
                               for x, b, r, e, d in _views(blocks, st["x"], st["b"], st["r"], st["e_x"], step))
        largest = float(np.max(np.abs(step), initial=0.0))
    r = st["r"]
    w_a = pairwise_sum(_leaf_sum(lambda b, v, out: B.block_precondition_forward(b, r[v], out), run)
                       for run in _leaf_runs(blocks, leaves))
    return ci, w_a, numbers, largest


def _leaf_sum(add_block, run) -> np.ndarray:
    """A leaf's attitude vector: its blocks added into one vector in block order
    (:mod:`~mcsweep.solver.reduction`, "Leaves"); ``add_block(block, rows, out)``."""
    out = np.zeros((run[0][1].n_coef, 3))
    for _, b, v in run:
        add_block(b, v, out)
    return out


def _back_task(item):
    """Last sweep of the preconditioner: z_s and the data part of N z kept; returned the
    attitude part of N z, and the shares of r'z and of the frame sums C z_s."""
    ci, blocks, _, st, z_a, leaves = item
    r = st["r"]
    z, nz = np.empty_like(r), np.empty_like(r)

    def add_block(b, v, out):
        z[v], nz[v], _ = B.block_precondition_back(b, r[v], z_a, out)

    ya = pairwise_sum(_leaf_sum(add_block, run) for run in _leaf_runs(blocks, leaves))
    st["z"], st["nz"] = z, nz
    g_s = st.get("g_s")
    numbers = pairwise_sum(np.r_[_dot(r, z), kernels.frame_sums(K, g, z)]
                           for r, z, K, g in _views(blocks, st["r"], st["z"], st["K"], st["g"]))
    if g_s is not None:  # G_s' z_s, the stars' share of the border's rows of N z
        numbers = np.r_[numbers, [pairwise_sum(_dot(gs, z) for gs, z in _views(blocks, g_s[j], z))
                                  for j in range(len(g_s))]]
    return ci, ya, numbers


def _direction_task(item):
    """N z completed with the prior and the frame penalty (``sums``: C z over all stars), then
    the new search direction ``p = z + beta p`` (``beta`` None: the first, ``p = z``) and
    ``q = N p`` by recursion; returned the share of p'q."""
    ci, blocks, _, st, sums, beta, w, z_c = item
    e_z = st["prior"] * st["z"]
    kernels.frame_apply(st["K"], st["g"], sums, w[0], w[1], e_z)
    nz = st.pop("nz") + e_z
    if z_c is not None:  # + G_s z_c: the border's columns of N z
        for j, c in enumerate(z_c):
            nz += c * st["g_s"][j]
    z = st.pop("z")
    if beta is None:
        st["p"], st["q"], st["e_p"] = z, nz, e_z
    else:
        st["p"] = z + beta * st["p"]
        st["q"] = nz + beta * st["q"]
        st["e_p"] = e_z + beta * st["e_p"]
    return ci, pairwise_sum(_dot(p, q) for p, q in _views(blocks, st["p"], st["q"]))


def _residual_task(item):
    """Residuals of the solution; returned the chunk's share of the stars' solution unless it
    stays with the chunk (``send_x`` False: :class:`ResidentProblem`)."""
    ci, blocks, hs, st, x_a, keep, send_x, x_c = item
    res = [B.block_residuals(b, h, x, x_a) for b, h, (x,) in zip(blocks, hs, _views(blocks, st["x"]))]
    if x_c is not None:
        res = [r - c @ x_c for r, c in zip(res, st["border"])]
    return ci, (res if keep else None), pairwise_sum(_dot(r, r) for r in res), (st["x"] if send_x else None)


def _dot(a, b) -> float:
    """``sum(a * b)`` by numpy's pairwise add-reduce, whose rounding, unlike BLAS ``ddot`` or
    einsum, does not depend on the operands' memory alignment."""
    return float(np.sum(np.multiply(a, b)))


def _fresh(obj):
    """Arrays copied into new allocations: results unpickled from a worker may sit at any
    memory alignment, and numpy's SIMD reductions (dot, einsum) may round differently
    with alignment; fresh copies behave as arrays computed in this process."""
    if isinstance(obj, np.ndarray):
        return np.array(obj, copy=True)
    if isinstance(obj, (list, tuple)):
        return type(obj)(_fresh(o) for o in obj)
    if isinstance(obj, dict):
        return {k: _fresh(v) for k, v in obj.items()}
    return obj


def _ordered(run, fn, items) -> list:
    """Results of ``run(fn, items)`` (any completion order) in the order of the items ``(ci, ...)``, as fresh arrays
    (:func:`_fresh`; an executor whose ``run`` has ``fresh_results`` gives them so already:
    the forked workers', :mod:`~mcsweep.solver.resident`, where a second copy of every
    attitude vector cost a third of the driver's time at AGIS's knots)."""
    fresh = getattr(run, "fresh_results", False)
    out = dict((r[0], r[1:] if fresh else _fresh(r[1:])) for r in run(fn, items))
    return [out[item[0]] for item in items]  # items (ci, ...): any chunks, not only 0 .. n - 1


def chunk_values(run, fn, items) -> list:
    """The one value of each chunk task ``fn`` returning ``(ci, value)``, run by ``run`` (any
    completion order), in chunk order and as fresh arrays (:func:`_fresh`)."""
    return [r[0] for r in _ordered(run, fn, items)]


class AttitudeNotDetermined(LinAlgError):
    """The attitude block of the normal equations is singular: some attitude coefficient is
    not determined by the data (knots closer than the stars' transits can fix; more unknowns
    than measurements in its support). ``coefficient``, ``axis``: the first one found (the
    factorisation's first non-positive pivot)."""

    def __init__(self, coefficient: int, axis: int):
        super().__init__(f"attitude coefficient {coefficient} (axis {axis}) is not determined by the data")
        self.coefficient, self.axis = int(coefficient), int(axis)


class ChunksLost(RuntimeError):
    """Raised by a resident executor when a worker and the chunk states it held were lost;
    its chunks' data are back on the cluster and the solution restarts (deterministic, so
    with the same bits)."""


#: Bytes of the banded Schur block summed at once in the setup pass (:func:`_absorption_task`):
#: the band is summed in that many slabs of its columns, so no process holds more than the
#: driver's one band beyond slabs of this size (one slab below 32 MiB: every problem with
#: fewer than ~3.5e5 attitude unknowns, e.g. 3 h knots at the paper's sizes).
SETUP_SLAB_BYTES = 1 << 25

#: Restarts of a solution after lost chunk states before the loss is raised.
MAX_RESTARTS = 3


# ---------------------------------------------------------------------- solver
def solve_global(problem: GlobalProblem, h, *, rtol: float = 1e-10, update_tol_uas: float = 1e-3,
                 error_tol: float | None = None, max_iter: int = 500,
                 min_iter: int = 2, log=None, chunk_stars: int | None = None,
                 residuals: bool = True, workers: int = 1, dask_client=None,
                 resident_chunks=None, border=None, attitude_start=None) -> GlobalSolution:
    """Solve ``N x = A' h`` by PCG from ``x = 0``, or from the attitude ``attitude_start`` (module notes).

    Parameters
    ----------
    problem : GlobalProblem
    h : array_like (m,) or None
        Normalised measurements (observed minus computed from the starting values:
        the scanning-law attitude and zero corrections), in observation order; None when
        they are kept with ``resident_chunks`` (built on the workers).
    rtol, update_tol_uas, error_tol, max_iter, min_iter : keyword-only
        Convergence criterion (module notes): with ``error_tol`` (in units of the formal
        uncertainty of every estimated quantity) the energy criterion, and ``rtol`` and
        ``update_tol_uas`` are not used.
    log : callable, optional
        Called with each :class:`ConvergenceRecord` (after a restart, from iteration 1 again).
    chunk_stars : int, optional, keyword-only
        Most stars per chunk task (rounded down to a power of two of blocks); default: as
        many as the workers' equal shares of the blocks allow (a few chunks per worker, so a
        pass returns a few attitude-sized vectors per worker, not one per block). Results do
        not depend on it.
    residuals : bool, keyword-only
        Return the residual of every measurement (``GlobalSolution.residuals``, 8 bytes
        per measurement); ``False`` keeps only their RMS.
    workers : int, keyword-only
        Forked processes that keep their share of the chunks and of the star vectors
        (:mod:`~mcsweep.solver.resident`); 1 (default) or no ``fork``: in-process. Results
        do not depend on it. (A map-like executor, one that sends a task's data with every
        call, cannot keep the star vectors between passes and is not accepted.)
    dask_client : distributed.Client, optional, keyword-only
        Every pass on a Dask cluster whose workers keep the chunks and their star vectors
        (:class:`~mcsweep.solver.dask_resident.DaskChunks`: scattered once, then only
        attitude-sized vectors travel); overrides ``workers``. Results do not depend on it.
    resident_chunks : DaskChunks, optional, keyword-only
        As ``dask_client``, with the chunks already on the workers; its chunk ``ci`` must be
        the problem's blocks of ``problem.chunks(chunk_stars)[ci]`` with their measurements.
    border : array_like (m, k), optional, keyword-only
        Normalised partials of ``k`` further unknowns that every measurement may depend on
        (a calibration, :mod:`~mcsweep.solver.calibration`), in observation order, without
        prior or frame constraint: the bordered system is solved (module notes, "Bordered
        unknowns") and they are returned as ``GlobalSolution.border``. In-process and forked
        workers only.
    attitude_start : array_like (n_coef, 3), optional, keyword-only
        Attitude coefficients [mas] PCG starts from (module notes, "Starting attitude"), e.g.
        the solution of the same data under another prior; coefficients without data are
        ignored (held at zero). The solution, residuals and stopping rule are those of the
        whole solution, the start included.
    """
    if h is None and resident_chunks is None:
        raise ValueError("the measurements h are needed unless they are on the workers (resident_chunks)")
    if h is not None:
        h = np.asarray(h, dtype=float)
        if h.size != problem.n_measurements:
            raise ValueError(f"h has {h.size} measurements, the problem {problem.n_measurements}")
    shares = max(1, int(workers)) if resident_chunks is None and dask_client is None else 1
    ranges = problem.chunks(chunk_stars, shares=shares)
    chunks = [problem.blocks[lo:hi] for lo, hi in ranges]
    # views when the rows are slices (in_block_order); None: kept with the resident chunks
    hs = None if h is None else [[h[b.rows] for b in bl] for bl in chunks]
    if resident_chunks is None and dask_client is not None:
        from .dask_resident import DaskChunks

        resident_chunks = DaskChunks.scatter(dask_client, list(zip(chunks, hs)))
    if error_tol is not None and not error_tol > 0:
        raise ValueError(f"error_tol={error_tol}: expected a positive fraction of the formal uncertainties")
    kw = dict(rtol=rtol, update_tol_uas=update_tol_uas, error_tol=error_tol,
              max_iter=max_iter, min_iter=min_iter, log=log, residuals=residuals)
    if attitude_start is not None:
        start = np.asarray(attitude_start, dtype=float)
        if start.shape != (problem.n_coef, 3) or not np.isfinite(start).all():
            raise ValueError(f"attitude_start has shape {start.shape}: expected ({problem.n_coef}, 3), finite")
        kw["start"] = np.where(problem.free, start, 0.0)
    states = [{} for _ in chunks]
    if border is not None:
        if h is None or resident_chunks is not None:
            raise ValueError("border unknowns are solved in-process or with forked workers, with h given")
        border = np.asarray(border, dtype=float).reshape(h.size, -1)
        for st, bl in zip(states, chunks):
            st["border"] = [np.ascontiguousarray(border[b.rows]) for b in bl]
        # C' h and C' C by numpy's pairwise sums (_dot): the same bits for any chunking
        kw["border_normals"] = (np.array([_dot(c, h) for c in border.T]),
                                np.array([[_dot(a, c) for c in border.T] for a in border.T]))
    if resident_chunks is not None:
        for attempt in range(MAX_RESTARTS + 1):
            try:
                return _pcg(problem, chunks, resident_chunks.run, reduced=getattr(resident_chunks, "reduced", None),
                            **kw)
            except ChunksLost:
                if attempt == MAX_RESTARTS:
                    raise
    owners = [share_of(lo, len(problem.blocks), shares) for lo, _ in ranges]
    with forked_chunks(list(zip(chunks, hs, states)), workers, owners=owners) as pool:
        if pool is None:  # in-process: the chunks and their states are these very objects
            items = {ci: (chunks[ci], hs[ci], states[ci]) for ci in range(len(chunks))}
            return _pcg(problem, chunks, partial(_in_process, items), **kw)
        return _pcg(problem, chunks, pool, **kw)


def remaining_error(steps) -> float:
    """``ERROR_SAFETY`` times the error ``|x* - x_k|_N`` extrapolated from the squared N-norms
    ``steps`` of the steps so far (module notes); NaN before ``ERROR_WINDOW + 1`` steps,
    infinite while they do not fall."""
    if len(steps) <= ERROR_WINDOW:
        return float("nan")
    last, first = steps[-1], steps[-1 - ERROR_WINDOW]
    if not 0.0 < last < first:
        return 0.0 if last == 0.0 else float("inf")
    q = (last / first) ** (1.0 / ERROR_WINDOW)
    return ERROR_SAFETY * math.sqrt(last * q / (1.0 - q))


def _in_process(chunks: dict, fn: Callable, items: Iterable) -> Iterator:
    """The in-process executor over chunks ``(blocks, measurements, state)`` it holds; items
    are ``(ci, *rest)`` as for the resident executors."""
    return (fn((item[0], *chunks[item[0]], *item[1:])) for item in items)


def _pcg(pb: GlobalProblem, chunks, run, *, rtol, update_tol_uas, error_tol, max_iter, min_iter,
         log, residuals, border_normals=None, start=None, reduced=None) -> GlobalSolution:
    """The PCG iteration of :func:`solve_global`; ``run(fn, items)`` runs chunk tasks whose items
    are ``(ci, *rest)`` on the executor that holds chunk ``ci`` and its state. ``border_normals``:
    ``(C'h, C'C)`` of the bordered unknowns, whose columns the chunks' states hold (None: none).
    ``reduced(fn, items, specs, fresh=)``: an executor that sums the chunks' outputs where they
    are (:meth:`~mcsweep.solver.dask_resident.DaskChunks.reduced`: a few sums per worker reach
    the driver, not one per chunk); None: the chunks' outputs are summed here."""
    m = pb.n_measurements
    stars = [slice(bl[0].first, bl[-1].first + bl[-1].n) for bl in chunks]
    n_ch = range(len(chunks))
    w = (pb.w_pos, pb.w_pm)
    levels = [run_level(0, len(bl)) for bl in chunks]
    # each chunk's leaves (local block ranges): its blocks' attitude vectors are summed per leaf
    bs, leaf = (pb.blocks[0].n if pb.blocks else 1), pb.leaf
    if any((bl[0].first // bs) % leaf for bl in chunks):
        raise ValueError(f"chunks must start at a leaf of {leaf} blocks (problem.chunks)")
    leaves = [[(j, min(j + leaf, len(bl))) for j in range(0, len(bl), leaf)] for bl in chunks]
    leaf_levels = [run_level(0, len(lv)) for lv in leaves]

    def total(values, add=None):
        """Sum over the chunks (each an aligned run of blocks) in the blocks' fixed tree."""
        return pairwise_sum(values, add, levels)

    def total_att(values, add=None):
        """Sum of the chunks' attitude vectors (each an aligned run of leaves) in the leaves' tree."""
        return pairwise_sum(values, add, leaf_levels)

    # the chunks' runs in the two trees (first block or leaf, level), for sums taken where the chunks are
    first_block = [bl[0].first // bs for bl in chunks]
    block_tree = first_block, levels
    leaf_tree = [f // leaf for f in first_block], leaf_levels

    sums = {"blocks": total, "leaves": total_att}

    def summed(fn, items, trees, *, fresh=True):
        """The outputs of the chunk tasks ``fn`` over all chunks, summed: ``trees[k]`` is
        ``("blocks" | "leaves", add)`` for a sum in that tree, or ``("max", None)``. Where the
        chunks are (``reduced``) or here from each chunk's outputs: the same bits. ``fresh``
        False (one output, added element by element): summed as received, each chunk's
        dropped once added (the setup's are large)."""
        if reduced is not None:
            specs = [("max",) if t == "max" else ("tree", *(block_tree if t == "blocks" else leaf_tree), add)
                     for t, add in trees]
            return reduced(fn, items, specs, fresh=fresh)
        if not fresh:
            ((t, add),) = trees
            got = {r[0]: r[1] for r in run(fn, items)}
            return [sums[t]((got.pop(i) for i in n_ch), add)]
        out = _ordered(run, fn, items)
        return [max(o[k] for o in out) if t == "max" else sums[t]((o[k] for o in out), add)
                for k, (t, add) in enumerate(trees)]

    # Setup pass: right-hand side, the stars' vectors on the workers, the banded Schur block.
    # The setup's numbers are only added element by element (no SIMD reduction whose rounding
    # could depend on where an unpickled array sits), so they are summed as received, without
    # _fresh's copies, each chunk's dropped once in the tree; and only the factor is kept
    # through the iterations.
    (glob,) = summed(_setup_task, [(i, None, None, pb.frame_means, leaves[i], start) if pb.stars_with_chunks else
                                   (i, pb.prior[sl], pb.K[sl], pb.frame_weights[sl], leaves[i], start)
                                   for i, sl in zip(n_ch, stars)], [("leaves", _add_setup)], fresh=False)
    free = pb.free
    b_a = np.where(free, glob["b_a"], 0.0)
    # the bordered unknowns (module notes): right-hand side b_c = C'h, their block D = C'C,
    # the attitude's rows of their columns G_a = A_a'C; the stars' rows G_s stay with the chunks.
    # Without any, k = 0: empty vectors, whose dots add an exact 0.0 to every sum.
    bordered = border_normals is not None
    b_c, D = border_normals if bordered else (np.zeros(0), np.zeros((0, 0)))
    G_a = np.where(free, glob["g_a"], 0.0) if bordered else np.zeros((0,) + b_a.shape)
    if start is not None:  # C'(h - A_a start): the chunks' right-hand sides were made from the same difference
        b_c = b_c - np.array([_dot(g, start) for g in G_a])
    D_inv = np.linalg.inv(D)
    b_norm = float(np.sqrt(glob["bb"] + _dot(b_a, b_a) + _dot(b_c, b_c))) or 1.0
    hh = glob["hh"]
    del glob
    # The absorption, slab by slab of the band's columns: each slab's sum over the chunks goes
    # straight into the band. A whole band is 12 x 2.3e6 doubles at AGIS's knots and the
    # paper's sizes, and summed whole each worker held up to five of them at once (a block's,
    # its leaf's and the tree's partial sums): the peak of the run (docs/table3.md, "Memory").
    # Every element is the same sum in the same order either way (blocks._schur_absorption).
    # The driver receives one slab per chunk before summing them in the fixed order (a few per
    # worker with forked workers; with many small Dask chunks, many).
    n_att = 3 * pb.n_coef
    cuts = share_bounds(n_att, -(-8 * (B.schur_bandwidth() + 1) * n_att // SETUP_SLAB_BYTES))
    band = None
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        (part,) = summed(_absorption_task, [(i, (lo, hi), leaves[i]) for i in n_ch], [("leaves", _add_in_place)],
                         fresh=False)
        if band is None:
            band = np.empty((part.shape[0], n_att))
        np.negative(part, out=band[:, lo:hi])
        del part
    band[-pb.naa_band.shape[0]:] += pb.naa_band
    fixed = ~free.ravel()
    band[:, fixed] = 0.0
    band[-1, fixed] = 1.0
    # LAPACK's banded Cholesky (what scipy's cholesky_banded calls), whose info is the first
    # non-positive leading minor: the unknown to name if the attitude is not determined
    chol, info = dpbtrf(np.asarray_chkfinite(band), lower=0)
    if info > 0:  # rounding in an attitude window no well-observed star constrains: a tiny ridge
        band[-1] += 1e-12 * np.maximum(pb.naa_band[-1], 1.0)
        chol, info = dpbtrf(band, lower=0)
        if info > 0:  # not rounding: the data leave attitude unknowns free
            raise AttitudeNotDetermined((info - 1) // 3, (info - 1) % 3)
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of the banded Cholesky factorisation")
    del band

    def precondition(r_a, r_c, w_a, beta):
        """``z = M^-1 r`` (symmetric block Gauss-Seidel with the banded Schur block; the first
        sweep's attitude part ``w_a`` from the forward task; the bordered unknowns by ``D^-1``),
        its ``r'z``, then on the workers ``N z`` and the new direction: returns ``z_a``,
        ``(N z)_a``, ``z_c``, ``(N z)_c``, ``r'z`` and the stars' share of ``p'q``."""
        w_a = np.where(free, r_a - w_a, 0.0)
        # chol is finite (dpbtrf succeeded on a checked band) and w_a is a sum of the passes: no
        # finiteness scan of the 12 x 2.3e6 factor every iteration (7 % of the driver's time at
        # AGIS's knots, py-spy)
        z_a = np.where(free, cho_solve_banded((chol, False), w_a.ravel(), check_finite=False).reshape(-1, 3), 0.0)
        nz_a, numbers = summed(_back_task, [(i, z_a, leaves[i]) for i in n_ch], [("leaves", None), ("blocks", None)])
        nz_a[~free] = z_a[~free]
        # N z's border rows G_s'z_s + G_a'z_a + D z_c (the chunks' dots after the frame sums); its
        # border columns G z_c
        z_c = D_inv @ r_c
        nz_c = numbers[7:] + np.array([_dot(g, z_a) for g in G_a]) + D @ z_c
        for g, c in zip(G_a, z_c):
            nz_a += c * g
        rz = float(numbers[0]) + _dot(r_a, z_a) + _dot(r_c, z_c)
        beta = None if beta is None else beta(rz)
        (pq_s,) = summed(_direction_task, [(i, numbers[1:7], beta, w, z_c if bordered else None) for i in n_ch],
                         [("blocks", None)])
        return z_a, nz_a, z_c, nz_c, rz, beta, float(pq_s)

    def forward(alpha):
        return tuple(summed(_forward_task, [(i, alpha, leaves[i]) for i in n_ch],
                            [("leaves", None), ("blocks", None), ("max", None)]))

    x_a, x_c = np.zeros_like(b_a), np.zeros_like(b_c)
    r_a, r_c = b_a.copy(), b_c.copy()
    w_a, _, _ = forward(None)
    p_a, q_a, p_c, q_c, rz, _, pq_s = precondition(r_a, r_c, w_a, None)
    p_a = p_a.copy()
    history, converged = [], False
    steps = []  # squared N-norms of the steps, for the error estimate
    t0 = time.perf_counter()
    for it in range(1, max_iter + 1):
        pq = pq_s + _dot(p_a, q_a) + _dot(p_c, q_c)
        if not pq > 0.0:  # exact solution reached, loss of positive definiteness, or not finite
            break
        alpha = rz / pq
        step_a = alpha * p_a
        x_a += step_a
        r_a -= alpha * q_a
        step_c = alpha * p_c
        x_c += step_c
        r_c -= alpha * q_c
        w_a, numbers, largest_s = forward(alpha)
        xbr, xex, step_pos2, rr_s = (float(v) for v in numbers)
        # |h - A x|^2 = h'h - 2 x'b + x'A'A x with A'A x = b - r - (N_p + F) x_s (A, x, b and r
        # with the bordered unknowns)
        res2 = hh - (xbr + _dot(x_a, b_a + r_a) + _dot(x_c, b_c + r_c)) - xex
        steps.append(alpha * rz)
        # From a starting attitude the first step also sets the stars (the start holds none of
        # them): a one-off, not part of the decay the extrapolation follows (module notes)
        error = remaining_error(steps if start is None else steps[1:]) if error_tol is not None else float("nan")
        rec = ConvergenceRecord(
            iteration=it,
            update_max_uas=UAS_PER_MAS * max(float(np.max(np.abs(step_a), initial=0.0)), largest_s,
                                             float(np.max(np.abs(step_c), initial=0.0))),
            update_rms_position_uas=UAS_PER_MAS * float(np.sqrt(step_pos2 / max(pb.n_stars, 1))),
            update_rms_attitude_uas=UAS_PER_MAS * float(np.sqrt(np.mean(np.sum(step_a ** 2, axis=1)))),
            residual_rms=float(np.sqrt(max(res2, 0.0) / m)) if m else 0.0,
            relative_residual=float(np.sqrt(rr_s + _dot(r_a, r_a) + _dot(r_c, r_c))) / b_norm,
            seconds=time.perf_counter() - t0, energy_decrease=alpha * rz, error_estimate=error)
        history.append(rec)
        if log is not None:
            log(rec)
        if it >= min_iter and (error <= error_tol if error_tol is not None else
                               rec.update_max_uas < update_tol_uas and rec.relative_residual < rtol):
            converged = True
            break
        if it == max_iter:
            break
        z_a, nz_a, z_c, nz_c, rz_new, beta, pq_s = precondition(r_a, r_c, w_a, lambda rz_new: rz_new / rz)
        p_a = z_a + beta * p_a
        q_a = nz_a + beta * q_a   # N p without another pass
        p_c = z_c + beta * p_c
        q_c = nz_c + beta * q_c
        rz = rz_new
    if start is not None:
        x_a = x_a + start
    out = _ordered(run, _residual_task, [(i, x_a, residuals, not pb.stars_with_chunks,
                                          x_c if bordered else None) for i in n_ch])
    res_all = None
    if residuals:
        res_all = np.empty(m)
        for b, rb in zip(pb.blocks, [r for o in out for r in o[0]]):
            res_all[b.rows] = rb
    ss = total(o[1] for o in out)
    x_s = None if pb.stars_with_chunks else np.concatenate([o[2] for o in out]) if out else np.zeros((0, 5))
    return GlobalSolution(x=x_s, attitude=x_a, cov=pb.src_inv, residuals=res_all,
                          residual_rms=float(np.sqrt(ss / m)) if m else float("nan"),
                          history=history, converged=converged, border=x_c if bordered else None)
