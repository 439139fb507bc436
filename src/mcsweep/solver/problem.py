"""The normal equations of the global solution, in blocks of stars.

Unknowns: the five astrometric parameters of ``n`` stars (Eq. 1 order, mas and mas/yr)
and the attitude spline coefficients (``n_coef x 3``, mas). The normal matrix

    N = [[N_ss + N_p + F, N_sa], [N_as, N_aa]]

(``N_p`` the prior of Eq. 18, ``F`` the frame penalty of :mod:`mcsweep.solver.frame`) is
never formed: the measurements are held in fixed blocks of stars
(:class:`~mcsweep.solver.blocks.StarBlock`, :func:`make_blocks`), and the solver applies
``N`` pass by pass over them (Bombrun et al. 2012, A&A 538, A77; the blocks' sums in the
fixed tree of :mod:`~mcsweep.solver.reduction`, so the problem, not the execution, sets
the rounding). :class:`GlobalProblem` holds the blocks in the driver, with each star's
inverse source block ``(N_ss + N_p)^-1``, the attitude band ``N_aa`` and the frame
constraint's weights; :class:`ResidentProblem` is its driver's side when the blocks and
every per-star array stay with their chunks on a cluster's workers (:func:`star_arrays`
makes those there). :func:`solver_chunks` is the rule that cuts the blocks into the
execution's chunks.

The frame constraint (zero weighted rotation and spin, Lindegren et al. 2012, A&A 538, A78,
Sect. 6.1) weights every star by its formal precision
(:func:`~mcsweep.solver.frame.normalised_weights`): with equal weights a loose prior lets
the constraint be met by the stars whose proper motions the data leave free, and the spin
of the well-observed stars and of the attitude is left to their priors, a near-null space
(measured: docs/solver_design.md, "Frame and preconditioner").
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from ..astrometry.design import tangent_triad
from . import blocks as B
from . import kernel_backend
from .attitude_update import free_coefficients
from .frame import normalised_weights, penalty_weights, precision_weights, rotation_matrices, typical_weights, weight_sums
from .observations import Measurements
from .reduction import chunk_ranges, leaf_blocks, pairwise_sum
from .source_update import solve_sources, source_normals

__all__ = ["GlobalProblem", "ResidentProblem", "make_blocks", "in_block_order", "solver_chunks", "star_arrays",
           "blocks_with_inverses", "attach_inverses", "SOLVER_BLOCK_STARS"]

#: Stars per solver block: the unit of the solver's reductions (module notes of
#: :mod:`~mcsweep.solver.reduction`). Why this size: every block adds one attitude-sized
#: vector per pass, so blocks hold many stars; where a block holds fewer measurements
#: than there are attitude unknowns (AGIS's 30 s knots), blocks are summed in leaves
#: (:func:`~mcsweep.solver.reduction.leaf_blocks`) so that this overhead stays small.
#: The value is part of the problem, not of the execution: the rounding of the sums, and
#: the primary experiment's noise streams (one per block), depend on it, so it is fixed.
SOLVER_BLOCK_STARS = 32768


def make_blocks(obs: Measurements, ra_deg, dec_deg, *, block_stars: int = SOLVER_BLOCK_STARS, compact: bool = False,
                first_star: int = 0) -> list:
    """The :class:`~mcsweep.solver.blocks.StarBlock` s of ``obs`` (without per-star inverses).

    ``ra_deg, dec_deg`` (``obs.n_stars``,): directions of ``obs``'s stars. ``rows`` index
    ``obs``'s measurements. ``obs`` may hold a part of the problem: its stars are
    ``first_star + obs.star`` (``first_star`` a multiple of ``block_stars``); the parts'
    blocks are then put in one observation order by :func:`in_block_order`. A problem
    built part by part (:meth:`GlobalProblem.from_blocks`) never holds all measurements'
    partials twice: each part's :class:`Measurements` can be dropped once its blocks are made.
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
    obs : Measurements
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
        Stars per reduction block (:data:`SOLVER_BLOCK_STARS`); part of the problem, not of the
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

    def __init__(self, obs: Measurements, prior_diagonal, ra_deg, dec_deg, *, block_stars: int = SOLVER_BLOCK_STARS,
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
        with their resident chunks only (:func:`~mcsweep.solver.solve.solve_global`'s ``resident_chunks``).
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
        # Frame constraint weights (module notes): each star's formal precision of
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
        kernels = kernel_backend.active()
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


def blocks_with_inverses(blocks, binv) -> list:
    """``blocks`` (a chunk's, consecutive) holding their stars' inverses ``binv (n, 5, 5)``,
    those of the chunk's stars in order: what one prior changes in a chunk kept where it is,
    the measurements staying (:meth:`~mcsweep.solver.dask_resident.DaskChunks.attached`)."""
    first = blocks[0].first
    return [dataclasses.replace(b, binv=binv[b.first - first:b.first - first + b.n]) for b in blocks]


def attach_inverses(chunk: tuple, binv) -> tuple:
    """A chunk ``(blocks, measurements, state)`` with its stars' inverses ``binv`` and a state
    of its own (:func:`blocks_with_inverses`): a chunk solved for another prior."""
    return blocks_with_inverses(chunk[0], binv), chunk[1], {}


class ResidentProblem:
    """The driver's side of a problem whose blocks, measurements and per-star arrays (data
    normal matrices, prior, inverses, frame weights, solution) all stay with their chunks, on
    a cluster's workers or held in this process (:class:`~mcsweep.solver.executors.HeldChunks`;
    :mod:`mcsweep.experiments.primary.prior_solution`): the block spans (or blocks), the
    attitude band, the frame's means and penalty weights. :func:`~mcsweep.solver.solve.solve_global` solves it
    with its ``resident_chunks`` only, and the stars' solution stays there too
    (:class:`~mcsweep.solver.pcg.GlobalSolution`'s ``x`` and ``cov`` are None)."""

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
