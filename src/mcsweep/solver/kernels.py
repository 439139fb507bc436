"""Compiled passes over a block's measurements: the two preconditioner sweeps of every PCG iteration.

These are the solver's hot path (every iteration reads every measurement three
times, and at AGIS's 30 s knots there are many iterations). In numpy each product of :mod:`~mcsweep.solver.blocks` is a vector
operation with its own temporaries, so one pass streams some 30 measurement-length
arrays through memory; here one loop reads each measurement's 70 stored bytes once and
keeps everything else in registers. Measured with ``benchmarks/bench_primary.py``
(docs/notes/table3/solver_cost.md, "Speed").

The loops run over the block's measurements in their stored (time) order and add into
the per-star and attitude sums in that order, one measurement after the other: no
reassociation (numba compiles without ``fastmath``), so a block's result does not
depend on the process, the memory alignment or the chunking, and the solver's fixed
reduction order over blocks (:mod:`~mcsweep.solver.reduction`) keeps solutions
bit-identical across workers and backends.

Notation as in :mod:`~mcsweep.solver.blocks`: ``src (3, m)`` partials w.r.t. (alpha*,
delta, parallax), ``t (m,)`` epochs, ``star (m,)`` star in the block, ``j0 (m,)`` first
spline coefficient, ``bval (4, m)`` spline values, ``pq (n, 6)`` each star's ``p, q``,
``binv (n, 5, 5)``.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["precondition_forward", "precondition_back", "frame_sums", "frame_apply", "band_scatter",
           "orthogonal_absorption"]

_jit = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False)


#: A run's attitude sums, (k, c) for spline value k and axis c, row-major: kept as a tuple
#: of scalars, i.e. in registers, while the run lasts.
_ZERO_RUN = (0.0,) * 12

_inline = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False,
                     inline="always")


@_inline
def _adjoint_add(acc, pq, s, bval, i, wd, wa):
    """``acc`` plus measurement ``i``'s attitude partials times its weight (``wd``, ``wa``:
    the weight times the star's partials w.r.t. delta and alpha*)."""
    w0 = wd * pq[s, 0] - wa * pq[s, 3]
    w1 = wd * pq[s, 1] - wa * pq[s, 4]
    w2 = wd * pq[s, 2] - wa * pq[s, 5]
    b0, b1, b2, b3 = bval[0, i], bval[1, i], bval[2, i], bval[3, i]
    return (acc[0] + b0 * w0, acc[1] + b0 * w1, acc[2] + b0 * w2,
            acc[3] + b1 * w0, acc[4] + b1 * w1, acc[5] + b1 * w2,
            acc[6] + b2 * w0, acc[7] + b2 * w1, acc[8] + b2 * w2,
            acc[9] + b3 * w0, acc[10] + b3 * w1, acc[11] + b3 * w2)


@_inline
def _flush(out, j, acc):
    """Add a run's sums to the attitude rows ``j .. j + 3``."""
    for k in range(4):
        for c in range(3):
            out[j + k, c] += acc[3 * k + c]


@_jit
def _forward(src, t, star, seg, seg_j0, bval, pq, y, out):
    """``out += A_a' A_s y`` for per-star ``y (n, 5)``: ``out (n_coef, 3)``.

    Measurements come in runs of equal first coefficient (``seg``, ``seg_j0``): a run's
    attitude sums are kept in registers and added to ``out`` once, which spares each
    measurement a chain of twelve dependent memory updates.
    """
    m = t.shape[0]
    for r in range(seg.shape[0]):
        hi = seg[r + 1] if r + 1 < seg.shape[0] else m
        acc = _ZERO_RUN
        for i in range(seg[r], hi):
            s = star[i]
            sa, sd, ti = src[0, i], src[1, i], t[i]
            v = sa * (y[s, 0] + ti * y[s, 3]) + sd * (y[s, 1] + ti * y[s, 4]) + src[2, i] * y[s, 2]
            wd, wa = sd * v, sa * v
            acc = _adjoint_add(acc, pq, s, bval, i, wd, wa)
        _flush(out, seg_j0[r], acc)


@_jit
def _back(src, t, star, seg, seg_j0, bval, pq, binv, r_s, z_a, z_s, ys, ya, u):
    """Last preconditioner sweep and ``A' A z`` (:func:`precondition_back`); ``u (m,)`` scratch.
    Runs of equal first coefficient as in :func:`_forward`."""
    n = r_s.shape[0]
    m = t.shape[0]
    acc = np.zeros((n, 5))
    for r in range(seg.shape[0]):  # u = A_a z_a, acc = A_s' u
        hi = seg[r + 1] if r + 1 < seg.shape[0] else m
        j = seg_j0[r]
        z00, z01, z02 = z_a[j, 0], z_a[j, 1], z_a[j, 2]
        z10, z11, z12 = z_a[j + 1, 0], z_a[j + 1, 1], z_a[j + 1, 2]
        z20, z21, z22 = z_a[j + 2, 0], z_a[j + 2, 1], z_a[j + 2, 2]
        z30, z31, z32 = z_a[j + 3, 0], z_a[j + 3, 1], z_a[j + 3, 2]
        for i in range(seg[r], hi):
            s = star[i]
            b0, b1, b2, b3 = bval[0, i], bval[1, i], bval[2, i], bval[3, i]
            v0 = b0 * z00 + b1 * z10 + b2 * z20 + b3 * z30
            v1 = b0 * z01 + b1 * z11 + b2 * z21 + b3 * z31
            v2 = b0 * z02 + b1 * z12 + b2 * z22 + b3 * z32
            ap = pq[s, 0] * v0 + pq[s, 1] * v1 + pq[s, 2] * v2
            aq = pq[s, 3] * v0 + pq[s, 4] * v1 + pq[s, 5] * v2
            sa, sd, ti = src[0, i], src[1, i], t[i]
            ui = sd * ap - sa * aq
            u[i] = ui
            wa, wd = sa * ui, sd * ui
            acc[s, 0] += wa
            acc[s, 1] += wd
            acc[s, 2] += src[2, i] * ui
            acc[s, 3] += ti * wa
            acc[s, 4] += ti * wd
    for s in range(n):  # z_s = B^-1 (r_s - A_s' u)
        for a in range(5):
            w = 0.0
            for b in range(5):
                w += binv[s, a, b] * (r_s[s, b] - acc[s, b])
            z_s[s, a] = w
    for r in range(seg.shape[0]):  # f = u + A_s z_s; ys = A_s' f, ya = A_a' f
        hi = seg[r + 1] if r + 1 < seg.shape[0] else m
        acc = _ZERO_RUN
        for i in range(seg[r], hi):
            s = star[i]
            sa, sd, ti = src[0, i], src[1, i], t[i]
            f = u[i] + sa * (z_s[s, 0] + ti * z_s[s, 3]) + sd * (z_s[s, 1] + ti * z_s[s, 4]) + src[2, i] * z_s[s, 2]
            wa, wd = sa * f, sd * f
            ys[s, 0] += wa
            ys[s, 1] += wd
            ys[s, 2] += src[2, i] * f
            ys[s, 3] += ti * wa
            ys[s, 4] += ti * wd
            acc = _adjoint_add(acc, pq, s, bval, i, wd, wa)
        _flush(ya, seg_j0[r], acc)


def precondition_forward(blk, y, out=None) -> np.ndarray:
    """``A_a' A_s y`` (n_coef, 3) of the block for per-star ``y (n, 5)`` (``B^-1 r_s``), added
    into ``out`` (C-contiguous float64, changed in place; default: zeros) and returned."""
    out = np.zeros((blk.n_coef, 3)) if out is None else out
    _forward(blk.src, blk.t, blk.star, blk.seg, blk.seg_j0, blk.bval, blk.pq, np.ascontiguousarray(y, dtype=float), out)
    return out


def precondition_back(blk, r_s, z_a, ya=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``z_s = B^-1 (r_s - A_s' A_a z_a)`` (n, 5) and ``A' A z`` as (stars (n, 5), attitude (n_coef, 3));
    the attitude part added into ``ya`` (as ``out`` of :func:`precondition_forward`)."""
    z_s, ys = np.empty((blk.n, 5)), np.zeros((blk.n, 5))
    ya = np.zeros((blk.n_coef, 3)) if ya is None else ya
    _back(blk.src, blk.t, blk.star, blk.seg, blk.seg_j0, blk.bval, blk.pq, blk.binv, np.ascontiguousarray(r_s, dtype=float),
          np.ascontiguousarray(z_a, dtype=float), z_s, ys, ya, np.empty(blk.t.shape[0]))
    return z_s, ys, ya


@_jit
def _frame_sums(K, g, xs, out):
    """The weighted mean rotation (out[:3]) and spin (out[3:]) of ``xs``, summed star after star."""
    for col, kk in ((0, 0), (3, 1)):
        c0 = 0.0
        c1 = 0.0
        c2 = 0.0
        for s in range(xs.shape[0]):
            a = g[s, kk] * xs[s, col]
            d = g[s, kk] * xs[s, col + 1]
            c0 += a * K[s, 0, 0] + d * K[s, 1, 0]
            c1 += a * K[s, 0, 1] + d * K[s, 1, 1]
            c2 += a * K[s, 0, 2] + d * K[s, 1, 2]
        out[col] = c0
        out[col + 1] = c1
        out[col + 2] = c2


@_jit
def _frame_apply(K, g, c, w, out):
    """``out += F x`` per star, given the sums ``c`` (6,) of :func:`_frame_sums` over all stars."""
    for col, kk in ((0, 0), (3, 1)):
        for s in range(out.shape[0]):
            f = w[kk] * g[s, kk]
            out[s, col] += f * (K[s, 0, 0] * c[col] + K[s, 0, 1] * c[col + 1] + K[s, 0, 2] * c[col + 2])
            out[s, col + 1] += f * (K[s, 1, 0] * c[col] + K[s, 1, 1] * c[col + 1] + K[s, 1, 2] * c[col + 2])


def frame_sums(K, g, xs) -> np.ndarray:
    """The six sums ``C x`` of the frame constraint (rotation, spin) over the stars of ``xs (n, 5)``:
    a block's share; the shares are added in the solver's fixed tree (:mod:`~mcsweep.solver.reduction`)."""
    out = np.zeros(6)
    _frame_sums(np.ascontiguousarray(K, dtype=float), np.ascontiguousarray(g, dtype=float),
                np.ascontiguousarray(xs, dtype=float), out)
    return out


def frame_apply(K, g, sums, w_pos: float, w_pm: float, out) -> np.ndarray:
    """``out += F x`` (n, 5) for the stars of ``K, g`` from the six sums of :func:`frame_sums` over
    *all* stars (``out`` C-contiguous float64, changed in place and returned)."""
    _frame_apply(np.ascontiguousarray(K, dtype=float), np.ascontiguousarray(g, dtype=float),
                 np.ascontiguousarray(sums, dtype=float), np.array([w_pos, w_pm]), out)
    return out


@_jit
def _band_scatter(ab, H, BH, base, tmp):
    width = ab.shape[1]
    L = ab.shape[0]
    nc = base.shape[0]
    for r in range(L):
        for c in range(r, L):
            for k in range(nc):  # the clusters' sums per unknown, in cluster order (np.bincount's)
                idx = base[k] + c
                if 0 <= idx < width:
                    w = H[0, r, k] * BH[0, c, k]
                    for i in range(1, H.shape[0]):
                        w += H[i, r, k] * BH[i, c, k]
                    tmp[idx] += w
            row = L - 1 + r - c
            for k in range(nc):  # then each into the band once (the later repeats add 0.0)
                idx = base[k] + c
                if 0 <= idx < width:
                    ab[row, idx] += tmp[idx]
                    tmp[idx] = 0.0


def band_scatter(ab, H, BH, base, scratch=None) -> None:
    """``ab[L - 1 + r - c, base + c] += sum_i H[i, r] * BH[i, c]`` for ``c >= r`` (``ab (L, width)``
    upper band storage, ``H, BH (5, L, clusters)``, ``base (clusters,)``; columns outside
    ``0 .. width - 1`` dropped, so ``ab`` may be a slab of a longer band with ``base`` counted
    from its first column): the Schur absorption's scatter of
    :func:`~mcsweep.solver.blocks.schur_absorption`, touching only the clusters' unknowns.
    The same bits as ``ab[row] += np.bincount(base + c, w, minlength=width)`` per ``(r, c)``:
    each unknown's sum in cluster order from zero, then added once (a bin is never -0.0, so
    adding a zero bin or the later repeats' zeros changes nothing). ``scratch``: zeros of
    ``ab``'s width, left zero (reuse it across calls: at AGIS's knots one is 2.3e6 doubles,
    and a block's absorption makes one call per batch of stars)."""
    if scratch is None:
        scratch = np.zeros(ab.shape[1])
    _band_scatter(ab, np.ascontiguousarray(H, dtype=float), np.ascontiguousarray(BH, dtype=float),
                  np.ascontiguousarray(base, dtype=np.int64), scratch)


@_jit
def _orthogonal_absorption(ab, A, Gt, prior, s_bounds, c_bounds, base):
    cols, L = ab.shape[1], Gt.shape[1]  # ab may be a slab of the band
    width = A.shape[1] + L
    most = 0
    for s in range(s_bounds.shape[0] - 1):
        most = max(most, s_bounds[s + 1] - s_bounds[s])
    Z = np.empty((most + 5, width))
    v = np.empty(most + 5)
    s = 0
    for c in range(c_bounds.shape[0] - 1):
        c0, k = c_bounds[c], c_bounds[c + 1] - c_bounds[c]
        while s_bounds[s + 1] <= c0:  # the clusters come star by star
            s += 1
        if base[c] + L <= 0 or base[c] >= cols:  # no column of this slab
            continue
        # Z = [[A_c, G_c], [A_other, 0], [N_p^1/2, 0]]: the star's rows, this cluster's first
        nr = 0
        for r in range(c0, c0 + k):
            for j in range(5):
                Z[nr, j] = A[r, j]
            for j in range(L):
                Z[nr, 5 + j] = Gt[r, j]
            nr += 1
        for r in range(s_bounds[s], s_bounds[s + 1]):
            if r < c0 or r >= c0 + k:
                for j in range(5):
                    Z[nr, j] = A[r, j]
                for j in range(L):
                    Z[nr, 5 + j] = 0.0
                nr += 1
        for p in range(5):
            for j in range(width):
                Z[nr, j] = 0.0
            Z[nr, p] = np.sqrt(prior[s, p])
            nr += 1
        # Householder reflections of the five source columns, applied to all columns: what
        # is left below them, T, has T'T = G_c'G_c - H'B^-1 H, the cluster's Schur block
        for j in range(5):
            norm2 = 0.0
            for i in range(j, nr):
                norm2 += Z[i, j] * Z[i, j]
            if norm2 == 0.0:
                continue
            alpha = -np.sqrt(norm2) if Z[j, j] >= 0.0 else np.sqrt(norm2)
            vv = 0.0
            for i in range(j, nr):
                v[i] = Z[i, j]
            v[j] -= alpha
            for i in range(j, nr):
                vv += v[i] * v[i]
            if vv == 0.0:
                continue
            for col in range(j, width):
                d = 0.0
                for i in range(j, nr):
                    d += v[i] * Z[i, col]
                f = 2.0 * d / vv
                for i in range(j, nr):
                    Z[i, col] -= f * v[i]
        for r in range(L):
            for cc in range(r, L):
                idx = base[c] + cc
                if idx < 0 or idx >= cols:
                    continue
                g = 0.0
                for i in range(c0, c0 + k):
                    g += Gt[i, r] * Gt[i, cc]
                t = 0.0
                for i in range(5, nr):
                    t += Z[i, 5 + r] * Z[i, 5 + cc]
                ab[L - 1 + r - cc, idx] += g - t


def orthogonal_absorption(ab, A, Gt, prior, s_bounds, c_bounds, base) -> None:
    """Add clusters' Schur absorption ``G_c'G_c - T'T`` into the upper band storage ``ab (L,
    width)`` (``ab[L - 1 + r - c, base + c]``, ``c >= r``; columns outside ``ab`` dropped), ``T``
    what Householder reflections of the five source columns leave of ``[[A_c, G_c], [A_other, 0],
    [N_p^1/2, 0]]`` (:func:`~mcsweep.solver.blocks.schur_absorption`, its orthogonal form).

    ``A (m, 5)``, ``Gt (m, L)``: source partials and attitude partials (placed in the cluster's
    window) of the rows, star by star and cluster by cluster; star ``s`` holds rows
    ``s_bounds[s] .. s_bounds[s + 1] - 1`` and has the prior diagonal ``prior[s] (5,)``; cluster
    ``c`` holds rows ``c_bounds[c] .. c_bounds[c + 1] - 1`` (within one star) and its first unknown
    is ``base[c]``, counted from ``ab``'s first column (``ab`` may be a slab of a longer band:
    clusters with no column in it are skipped, columns outside it dropped). Plain loops in a
    fixed order (no LAPACK, whose kernels differ between CPU models), so the bits are the same
    on every worker."""
    _orthogonal_absorption(ab, np.ascontiguousarray(A, dtype=float), np.ascontiguousarray(Gt, dtype=float),
                           np.ascontiguousarray(prior, dtype=float),
                           *(np.ascontiguousarray(a, dtype=np.int64) for a in (s_bounds, c_bounds, base)))
