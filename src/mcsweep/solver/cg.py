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
``q = N z + beta q``): chunk tasks of :mod:`~mcsweep.solver.blocks` that go through a
caller-supplied ``run(fn, items)`` (the sweep's executor; by default only the one-off
passes, see :func:`solve_global`) and are summed in the fixed order of
:mod:`~mcsweep.solver.reduction`, so the solution is bit-identical for any chunking,
backend and number of workers.

Convergence criterion (stated for users): stop after iteration ``k >= min_iter`` when
both

* the relative residual of the normal equations ``|b - N x| / |b| < rtol``
  (recursively updated), and
* the largest change of any unknown in that iteration (attitude coefficients and all
  five parameters of every star, mas or mas/yr) is below ``update_tol_uas``
  microarcseconds;

or after ``max_iter`` iterations (then ``converged = False``). Every iteration is
logged (update norms in microarcsec, RMS of the normalised residuals, relative
residual).
"""

from __future__ import annotations

import copy
import dataclasses
import time
from functools import partial
from typing import Callable, Iterable, Iterator

import numpy as np
from scipy.linalg import LinAlgError, cho_solve_banded, cholesky_banded

from ..astrometry.design import tangent_triad
from . import blocks as B
from . import kernels
from .attitude_update import free_coefficients
from .frame import precision_weights, rotation_matrices
from .observations import Observations
from .reduction import chunk_ranges, pairwise_sum
from .resident import forked_chunks
from .source_update import solve_sources, source_normals

__all__ = ["GlobalProblem", "ConvergenceRecord", "GlobalSolution", "solve_global", "make_blocks", "in_block_order",
           "UAS_PER_MAS",
           "BLOCK_STARS", "sequential_run"]

UAS_PER_MAS = 1000.0
#: Stars per reduction block (module notes of :mod:`~mcsweep.solver.reduction`). Every
#: block adds one attitude-sized vector per pass, so blocks must hold many more
#: measurements than there are attitude unknowns to keep that overhead small.
BLOCK_STARS = 32768


def sequential_run(fn: Callable, items: Iterable) -> Iterator:
    """The in-process executor: ``fn(item)`` for every item, in order."""
    return (fn(item) for item in items)


@dataclasses.dataclass
class ConvergenceRecord:
    """One iteration: update norms [microarcsec], residual RMS, relative residual, wall time."""

    iteration: int
    update_max_uas: float
    update_rms_position_uas: float
    update_rms_attitude_uas: float
    residual_rms: float
    relative_residual: float
    seconds: float


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
                    n_measurements: int) -> "GlobalProblem":
        """The problem from blocks made part by part (:func:`make_blocks`).

        ``blocks`` cover stars ``0 .. n - 1`` in order with one block size, their rows
        ``0 .. n_measurements - 1`` (the observation order); ``normals`` (n, 5, 5) the
        stars' data normal matrices (:func:`~mcsweep.solver.source_update.source_normals`
        of the parts, concatenated).
        """
        blocks = list(blocks)
        firsts = [b.first for b in blocks]
        sizes = {b.n for b in blocks[:-1]}
        if firsts != [i * blocks[0].n for i in range(len(blocks))] or len(sizes) > 1 or \
                sum(b.n for b in blocks) != len(normals):
            raise ValueError("blocks must cover the stars in order with one block size")
        self = cls.__new__(cls)
        self._assemble(blocks, np.asarray(normals, dtype=float), prior_diagonal, ra_deg, dec_deg,
                       n_coef=int(n_coef), n_measurements=int(n_measurements))
        return self

    def _assemble(self, blocks, normals, prior_diagonal, ra_deg, dec_deg, *, n_coef, n_measurements):
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
        self.naa_band = pairwise_sum(B.att_band(b) for b in self.blocks)
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
        self.frame_weights = np.column_stack([g[:, 0] / g[:, 0].mean(), g[:, 1] / g[:, 1].mean()])
        # Frame penalty weights: one typical star's position (proper-motion) weight per
        # unit of mean rotation, so the constrained directions are as well conditioned
        # as a star (any positive weight gives the same stars for the orientation).
        self.w_pos = float(np.median(N_src[:, 0, 0] + N_src[:, 1, 1])) / (2.0 * n)
        self.w_pm = float(np.median(N_src[:, 3, 3] + N_src[:, 4, 4] + 2 * self.prior[:, 3])) / (2.0 * n)

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
        (one compiled pass over the stars, summed in star order,
        :func:`~mcsweep.solver.kernels.frame_penalty`)."""
        return kernels.frame_penalty(self.K, self.frame_weights, xs, self.w_pos, self.w_pm)

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
            star[b.rows], j0[b.rows] = b.star + b.first, b.j0
            src[b.rows], att[b.rows], bval[b.rows] = B.src_rows(b).T, B.att_rows(b).T, b.bval.T
        return star, src, att, j0, bval

    @property
    def nbytes_per_measurement(self) -> float:
        """Bytes held per measurement by the blocks (partials, indices, per-star inverses)."""
        return sum(b.nbytes for b in self.blocks) / max(self.n_measurements, 1)

    def chunks(self, chunk_stars: int | None) -> list[tuple[int, int]]:
        """Block ranges of the execution chunks (a power of two of blocks, at most ``chunk_stars``)."""
        bs = self.blocks[0].n if self.blocks else 1
        return chunk_ranges(len(self.blocks), 1 if chunk_stars is None else max(1, int(chunk_stars) // bs))



# ---------------------------------------------------------------------- chunk tasks
def _add_setup(a: dict, b: dict) -> dict:
    return {k: a[k] + b[k] for k in a}


def _setup_task(item):
    ci, blocks, hs = item
    parts = [B.block_setup(b, h) for b, h in zip(blocks, hs)]
    b_s = np.concatenate([p.pop("b_s") for p in parts])
    return ci, pairwise_sum(parts, _add_setup), b_s


# Every task's item starts (chunk index, blocks, measurements): what a resident worker keeps.
def _forward_task(item):
    ci, blocks, _, r_s = item
    return ci, pairwise_sum(B.block_precondition_forward(b, r_s[b.first - blocks[0].first:][:b.n])
                            for b in blocks)


def _back_task(item):
    ci, blocks, _, r_s, z_a = item
    parts = [B.block_precondition_back(b, r_s[b.first - blocks[0].first:][:b.n], z_a) for b in blocks]
    return (ci, np.concatenate([q[0] for q in parts]), np.concatenate([q[1] for q in parts]),
            pairwise_sum(q[2] for q in parts))


def _residual_task(item):
    ci, blocks, hs, x_s, x_a, keep = item
    res = [B.block_residuals(b, h, x_s[b.first - blocks[0].first:][:b.n], x_a) for b, h in zip(blocks, hs)]
    return ci, (res if keep else None), pairwise_sum(_dot(r, r) for r in res)


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
    """Results of ``run(fn, items)`` (any completion order) in item order."""
    out = dict((r[0], _fresh(r[1:])) for r in run(fn, items))
    return [out[i] for i in range(len(items))]


# ---------------------------------------------------------------------- solver
def solve_global(problem: GlobalProblem, h, *, rtol: float = 1e-10, update_tol_uas: float = 1e-3,
                 max_iter: int = 500, min_iter: int = 2, log=None, run: Callable | None = None,
                 chunk_stars: int | None = None, run_iterations: Callable | None = None,
                 residuals: bool = True, workers: int = 1, dask_client=None,
                 resident_chunks=None) -> GlobalSolution:
    """Solve ``N x = A' h`` by PCG from ``x = 0`` (module notes).

    Parameters
    ----------
    problem : GlobalProblem
    h : array_like (m,)
        Normalised measurements (observed minus computed from the starting values:
        the scanning-law attitude and zero corrections), in observation order.
    rtol, update_tol_uas, max_iter, min_iter : keyword-only
        Convergence criterion (module notes).
    log : callable, optional
        Called with each :class:`ConvergenceRecord`.
    run : callable, optional, keyword-only
        Executor ``run(fn, items) -> iterator of fn(item)`` in any order, e.g. from
        :func:`mcsweep.sweep.execution.executor`, for the one-off passes (the setup pass
        that accumulates the right-hand sides and the banded Schur block, and the final
        residuals); default in-process. On one machine it does not pay: joblib loky with
        2 workers made a 2-iteration solve of 32000 stars (2.8e5 measurements, 4 blocks)
        take 10.2 s wall against 1.5 s in-process (shared machine, load ~8); it is meant
        for a Dask cluster with more cores than data transfer costs.
    run_iterations : callable, optional, keyword-only
        Executor for the two passes of every iteration; default in-process. Measured
        (16000 stars, 1.4e5 measurements, 2 chunks): joblib loky with 2 workers took 5.8x
        the wall time of in-process, threads 1.2x: a map-like executor re-sends every
        chunk's measurements each call, which costs more than the pass itself. Pass
        ``run`` here only for an executor whose workers keep their data (on one machine:
        ``workers``).
    chunk_stars : int, optional, keyword-only
        Stars per chunk task (rounded down to a power of two of blocks); default one
        block per task. Results do not depend on it.
    residuals : bool, keyword-only
        Return the residual of every measurement (``GlobalSolution.residuals``, 8 bytes
        per measurement); ``False`` keeps only their RMS.
    workers : int, keyword-only
        Forked processes that keep their share of the chunks (:mod:`~mcsweep.solver.resident`)
        for every pass not given to ``run`` / ``run_iterations``; 1 (default) or no ``fork``:
        in-process. Results do not depend on it.
    dask_client : distributed.Client, optional, keyword-only
        Every pass on a Dask cluster whose workers keep the chunks
        (:class:`~mcsweep.solver.dask_resident.DaskChunks`: scattered once, then only the
        per-pass vectors travel); overrides ``run``, ``run_iterations`` and ``workers``.
        Results do not depend on it.
    resident_chunks : DaskChunks, optional, keyword-only
        As ``dask_client``, with the chunks already on the workers (built there); its
        chunk ``ci`` must be the problem's blocks of ``problem.chunks(chunk_stars)[ci]``
        with their measurements.
    """
    h = np.asarray(h, dtype=float)
    ranges = problem.chunks(chunk_stars)
    chunks = [problem.blocks[lo:hi] for lo, hi in ranges]
    hs = [[h[b.rows] for b in bl] for bl in chunks]  # views when the rows are slices (in_block_order)
    if resident_chunks is None and dask_client is not None:
        from .dask_resident import DaskChunks

        resident_chunks = DaskChunks.scatter(dask_client, list(zip(chunks, hs)))
    if resident_chunks is not None:
        return _pcg(problem, h, chunks, hs, resident_chunks.run, resident_chunks.run, rtol=rtol,
                    update_tol_uas=update_tol_uas, max_iter=max_iter, min_iter=min_iter, log=log,
                    residuals=residuals)
    with forked_chunks(list(zip(chunks, hs)), workers if run_iterations is None else 1) as pool:
        return _pcg(problem, h, chunks, hs, run or pool or sequential_run, run_iterations or pool or sequential_run,
                    rtol=rtol, update_tol_uas=update_tol_uas, max_iter=max_iter, min_iter=min_iter, log=log,
                    residuals=residuals)


def _pcg(pb: GlobalProblem, h, chunks, hs, run, run_it, *, rtol, update_tol_uas, max_iter, min_iter, log,
         residuals) -> GlobalSolution:
    """The PCG iteration of :func:`solve_global` with its executors chosen."""
    stars = [slice(bl[0].first, bl[-1].first + bl[-1].n) for bl in chunks]

    # Setup pass: right-hand side and the banded Schur preconditioner of the attitude.
    res = _ordered(run, _setup_task, [(i, bl, hh) for i, (bl, hh) in enumerate(zip(chunks, hs))])
    glob = pairwise_sum((r[0] for r in res), _add_setup)
    free = pb.free
    b_s = np.concatenate([r[1] for r in res])
    b_a = np.where(free, glob["b_a"], 0.0)
    b_norm = float(np.sqrt(_dot(b_s, b_s) + _dot(b_a, b_a))) or 1.0
    band = -glob["absorption"]
    band[-pb.naa_band.shape[0]:] += pb.naa_band
    fixed = ~free.ravel()
    band[:, fixed] = 0.0
    band[-1, fixed] = 1.0
    try:
        chol = cholesky_banded(band, lower=False)
    except LinAlgError:  # rounding in an attitude window no well-observed star constrains: a tiny ridge
        band[-1] += 1e-12 * np.maximum(pb.naa_band[-1], 1.0)
        chol = cholesky_banded(band, lower=False)

    def extra_s(v_s):  # the non-data part of the source rows: prior and frame penalty
        return pb.prior * v_s + pb.frame_penalty(v_s)

    def precondition(r_s, r_a):
        """``z = M^-1 r`` (symmetric block Gauss-Seidel with the banded Schur block) and ``N z``."""
        # the same slice objects in both passes: an executor whose workers keep data
        # (mcsweep.solver.dask_resident) then sends each chunk's slice once
        rs = [r_s[sl] for sl in stars]
        fwd = _ordered(run_it, _forward_task, [(i, bl, hh, rs[i]) for i, (bl, hh) in enumerate(zip(chunks, hs))])
        w_a = np.where(free, r_a - pairwise_sum(f[0] for f in fwd), 0.0)
        z_a = np.where(free, cho_solve_banded((chol, False), w_a.ravel()).reshape(-1, 3), 0.0)
        back = _ordered(run_it, _back_task, [(i, bl, hh, rs[i], z_a) for i, (bl, hh) in enumerate(zip(chunks, hs))])
        z_s = np.concatenate([o[0] for o in back])
        e_s = extra_s(z_s)
        nz_s = np.concatenate([o[1] for o in back]) + e_s
        nz_a = pairwise_sum(o[2] for o in back)
        nz_a[~free] = z_a[~free]
        return z_s, z_a, nz_s, nz_a, e_s

    hh = glob["hh"]
    x_s, x_a = np.zeros_like(b_s), np.zeros_like(b_a)
    r_s, r_a = b_s.copy(), b_a.copy()
    p_s, p_a, q_s, q_a, e_p = precondition(r_s, r_a)
    e_x = np.zeros_like(x_s)  # (N_p + F) x_s and (N_p + F) p_s by the same recursions as x and q
    rz = float(_dot(r_s, p_s) + _dot(r_a, p_a))
    history, converged = [], False
    t0 = time.perf_counter()
    for it in range(1, max_iter + 1):
        pq = float(_dot(p_s, q_s) + _dot(p_a, q_a))
        if pq <= 0.0:  # exact solution reached (or loss of positive definiteness)
            break
        alpha = rz / pq
        x_s += alpha * p_s
        x_a += alpha * p_a
        e_x += alpha * e_p
        r_s -= alpha * q_s
        r_a -= alpha * q_a
        # |h - A x|^2 = h'h - 2 x'b + x'A'A x with A'A x = b - r - (N_p + F) x_s
        res2 = (hh - float(_dot(x_s, b_s + r_s) + _dot(x_a, b_a + r_a))
                - _dot(x_s, e_x))
        step_s, step_a = alpha * p_s, alpha * p_a
        rec = ConvergenceRecord(
            iteration=it,
            update_max_uas=UAS_PER_MAS * max(float(np.max(np.abs(step_a), initial=0.0)),
                                             float(np.max(np.abs(step_s), initial=0.0))),
            update_rms_position_uas=UAS_PER_MAS * float(np.sqrt(np.mean(np.sum(step_s[:, :2] ** 2, axis=1)))),
            update_rms_attitude_uas=UAS_PER_MAS * float(np.sqrt(np.mean(np.sum(step_a ** 2, axis=1)))),
            residual_rms=float(np.sqrt(max(res2, 0.0) / h.size)) if h.size else 0.0,
            relative_residual=float(np.sqrt(_dot(r_s, r_s) + _dot(r_a, r_a))) / b_norm,
            seconds=time.perf_counter() - t0)
        history.append(rec)
        if log is not None:
            log(rec)
        if it >= min_iter and rec.update_max_uas < update_tol_uas and rec.relative_residual < rtol:
            converged = True
            break
        z_s, z_a, nz_s, nz_a, e_z = precondition(r_s, r_a)
        rz_new = float(_dot(r_s, z_s) + _dot(r_a, z_a))
        beta = rz_new / rz
        p_s, p_a = z_s + beta * p_s, z_a + beta * p_a
        q_s, q_a = nz_s + beta * q_s, nz_a + beta * q_a   # N p without another pass
        e_p = e_z + beta * e_p
        rz = rz_new
    out = _ordered(run, _residual_task, [(i, bl, hh_, x_s[sl], x_a, residuals)
                                          for i, (bl, hh_, sl) in enumerate(zip(chunks, hs, stars))])
    res_all = None
    if residuals:
        res_all = np.empty(h.size)
        for b, rb in zip(pb.blocks, [r for o in out for r in o[0]]):
            res_all[b.rows] = rb
    ss = pairwise_sum(o[1] for o in out)
    return GlobalSolution(x=x_s, attitude=x_a, cov=pb.src_inv, residuals=res_all,
                          residual_rms=float(np.sqrt(ss / h.size)) if h.size else float("nan"),
                          history=history, converged=converged)
