"""Blocks of stars: their measurements in compact form and the per-block work of the solver.

A :class:`StarBlock` holds the measurements of a fixed range of stars in time order,
with the partials stored compactly, 70 bytes per measurement: the partials w.r.t.
position and parallax, the epoch (the proper-motion partials are the position partials
times the epoch, exactly as Eq. 1's design matrix forms them), 4 B-spline values, the
first coefficient index and the star's index in the block; plus, per star, its tangent
directions ``p, q`` and its inverse source block ``B_i^-1 = (N_ss,i + N_p,i)^-1``.

The attitude partials are not stored: a measurement along ``a = s_a p + s_d q`` (its
partials w.r.t. ``alpha*, delta`` are ``s_a, s_d``) changes under a small rotation
``delta`` of the instrument by ``-(u x a) . delta = (s_d p - s_a q) . delta``
(:mod:`~mcsweep.solver.observations`), so they follow from the position partials and the
star's ``p, q`` (they agree with the explicit ones to 2.5e-16 relative; the problem solved
is the one with these partials, :meth:`~mcsweep.solver.problem.GlobalProblem.design`).

The functions here are the per-block work of the chunk tasks of :mod:`mcsweep.solver.tasks`: module-level,
picklable, pure (arguments in, results out), so any executor (joblib processes, a Dask
cluster) can run them. Each returns the block's contribution to the global sums; the
caller adds contributions in the fixed order of :mod:`~mcsweep.solver.reduction`.

Notation (Bombrun et al. 2012, A&A 538, A77, Sect. 2): ``A_s``, ``A_a`` source and
attitude parts of the normalised design; ``B = N_ss + N_p`` block-diagonal over stars;
``N_as = A_a' A_s``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from . import kernel_backend
from .attitude_update import band_of_rows

__all__ = ["StarBlock", "BlockSpan", "gather", "spline_values", "att_rows", "src_rows", "att_forward", "att_adjoint", "att_band", "src_forward",
           "src_adjoint", "block_setup", "block_precondition_forward", "block_precondition_back", "block_residuals",
           "block_normal_apply", "schur_absorption", "ill_conditioned", "schur_bandwidth"]

_AX, _NB, _NP = 3, 4, 5


@dataclasses.dataclass
class StarBlock:
    """Measurements of stars ``first .. first + n - 1``, sorted by star (module notes).

    Attributes
    ----------
    first, n : int
        First star (index into the solution's stars) and number of stars.
    rows : ndarray (m,) int or slice
        Index of each measurement in the problem's observation order (a slice when the
        block's measurements are contiguous in it, :func:`~mcsweep.solver.problem.in_block_order`).
    star : ndarray (m,) int16 or int32
        Star of each measurement within the block (0 .. n - 1).
    src : ndarray (3, m)
        Normalised partials w.r.t. (dalpha*, ddelta, parallax) (one contiguous row per
        parameter: the passes read them row by row).
    t : ndarray (m,)
        Epoch minus the reference epoch [Julian years]: the proper-motion partials are
        ``t * src[0]``, ``t * src[1]``.
    pq : ndarray (n, 6)
        Each star's tangent directions ``p`` (columns 0-2) and ``q`` (columns 3-5), ICRS
        (one row per star: the compiled passes read a star's six values together).
    j0 : ndarray (m,) int32
        First spline coefficient touching the epoch.
    bval : ndarray (4, m)
        B-spline values.
    binv : ndarray (n, 5, 5)
        ``(N_ss + N_p)^-1`` per star.
    seg, seg_j0 : ndarray
        The measurements are in time order (``j0`` ascending, then by star): run ``r`` of
        equal ``j0`` starts at ``seg[r]`` and has ``j0 = seg_j0[r]``. The attitude sums are
        then segment sums (:func:`numpy.add.reduceat`, sequential memory access) instead
        of scatters over the whole attitude vector.
    n_coef : int
        Spline coefficients per axis.
    """

    first: int
    n: int
    rows: np.ndarray
    star: np.ndarray
    src: np.ndarray
    t: np.ndarray
    pq: np.ndarray
    j0: np.ndarray
    bval: np.ndarray
    binv: np.ndarray
    n_coef: int
    seg: np.ndarray
    seg_j0: np.ndarray

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, f.name).nbytes for f in dataclasses.fields(self)
                   if isinstance(getattr(self, f.name), np.ndarray))


# ------------------------------------------------------------------ elementary products
# Short sums are written as explicit element-wise accumulations in a fixed order, not
# einsum/matmul: numpy's SIMD reductions may round differently with the memory
# alignment of their operands, which differs between processes (pickled copies), and
# the results must be bit-identical on any worker (:mod:`~mcsweep.solver.reduction`).

@dataclasses.dataclass
class BlockSpan:
    """Where a :class:`StarBlock` that lives elsewhere (on a Dask worker, built there) sits in
    the problem: its stars ``first .. first + n - 1``, its measurements ``rows`` (a slice of
    the observation order), and the per-star inverses the driver sets for a prior. What the
    driver's side of the solver reads of a block (:mod:`~mcsweep.solver.problem`)."""

    first: int
    n: int
    rows: slice
    binv: np.ndarray | None = None


def _rowdot(a, b) -> np.ndarray:
    """``sum_k a[..., k] * b[..., k]`` over the last axis, accumulated left to right."""
    out = a[..., 0] * b[..., 0]
    for k in range(1, a.shape[-1]):
        out += a[..., k] * b[..., k]
    return out


def gather(blk: StarBlock, sel=slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """Per measurement of ``sel``: its star (``intp``, so gathers skip a conversion) and the
    star's ``p, q`` (6, m). One task computes it once and passes it to every product
    (``gathered=``) instead of each product gathering again."""
    star = blk.star[sel].astype(np.intp)
    return star, blk.pq.take(star, axis=0).T


def att_rows(blk: StarBlock, sel=slice(None), gathered=None) -> np.ndarray:
    """Attitude axis partials ``(3, m)`` of the measurements ``sel`` (module notes)."""
    s_a, s_d = blk.src[0, sel], blk.src[1, sel]
    pq = (gathered or gather(blk, sel))[1]
    return np.stack([s_d * pq[c] - s_a * pq[3 + c] for c in range(_AX)])


def src_rows(blk: StarBlock, sel=slice(None)) -> np.ndarray:
    """The five source partials ``(5, m)`` of the measurements ``sel``."""
    t = blk.t[sel]
    s_a, s_d = blk.src[0, sel], blk.src[1, sel]
    return np.stack([s_a, s_d, blk.src[2, sel], t * s_a, t * s_d])


def spline_values(blk: StarBlock, p) -> np.ndarray:
    """The attitude correction with coefficients ``p (n_coef, 3)`` at every epoch of the
    block, ``(3, m)`` [mas], from the block's own spline values (no new basis evaluation)."""
    pt = np.ascontiguousarray(np.asarray(p, dtype=float).T)
    j = [blk.j0.astype(np.intp) + k for k in range(_NB)]
    out = np.empty((_AX, blk.j0.size))
    for c in range(_AX):
        out[c] = blk.bval[0] * pt[c].take(j[0])
        for k in range(1, _NB):
            out[c] += blk.bval[k] * pt[c].take(j[k])
    return out


def att_forward(blk: StarBlock, p, gathered=None) -> np.ndarray:
    """``A_a p`` (m,) for attitude coefficients ``p (n_coef, 3)``; ``gathered`` from :func:`gather`."""
    pq = (gathered or gather(blk))[1]
    value = spline_values(blk, p)
    # the correction at each epoch projected on p and q of the star
    along_p = pq[0] * value[0] + pq[1] * value[1] + pq[2] * value[2]
    along_q = pq[3] * value[0] + pq[4] * value[1] + pq[5] * value[2]
    return blk.src[1] * along_p - blk.src[0] * along_q


def att_adjoint(blk: StarBlock, v, gathered=None) -> np.ndarray:
    """``A_a' v`` (n_coef, 3) for values ``v (m,)`` of the block's measurements."""
    out = np.zeros((blk.n_coef, _AX))
    if blk.j0.size == 0:
        return out
    v = np.asarray(v, dtype=float)
    w_d, w_a = blk.src[1] * v, blk.src[0] * v
    pq = (gathered or gather(blk))[1]
    for c in range(_AX):
        wc = w_d * pq[c] - w_a * pq[3 + c]
        for k in range(_NB):
            out[blk.seg_j0 + k, c] += np.add.reduceat(blk.bval[k] * wc, blk.seg)
    return out


def att_band(blk: StarBlock) -> np.ndarray:
    """The block's ``N_aa`` in upper band storage (:func:`~mcsweep.solver.attitude_update.band_of_rows`)."""
    G = (blk.bval[:, None, :].astype(float) * att_rows(blk)[None, :, :]).reshape(_AX * _NB, -1).T
    return band_of_rows(blk.j0, G, blk.n_coef)


def src_forward(blk: StarBlock, x, gathered=None) -> np.ndarray:
    """``A_s x`` (m,) for per-star parameters ``x (n, 5)``."""
    star = gathered[0] if gathered else blk.star.astype(np.intp)
    xs = np.asarray(x, dtype=float).T.take(star, axis=1)  # (5, m)
    return blk.src[0] * (xs[0] + blk.t * xs[3]) + blk.src[1] * (xs[1] + blk.t * xs[4]) + blk.src[2] * xs[2]


def src_adjoint(blk: StarBlock, v, gathered=None) -> np.ndarray:
    """``A_s' v`` (n, 5)."""
    w_a, w_d = blk.src[0] * v, blk.src[1] * v
    star = gathered[0] if gathered else blk.star.astype(np.intp)
    return np.stack([np.bincount(star, w, minlength=blk.n)
                     for w in (w_a, w_d, blk.src[2] * v, blk.t * w_a, blk.t * w_d)], axis=1)


def _binv(blk: StarBlock, x) -> np.ndarray:
    return _rowdot(blk.binv, x[:, None, :])


# ------------------------------------------------------------------ setup
#: Consecutive first coefficients ``j0`` whose measurements of one star form one cluster
#: of :func:`schur_absorption` (its band then has ``3 (SCHUR_WINDOW + 3) - 1`` super-diagonals).
#: Wider windows keep more of each star's absorption but barely pay: measured (4000 stars,
#: one year, 1-day knots, priors 1 / 10 / 1000 mas) 36 / 43 / 51 iterations with 1, 36 / 39 /
#: 46 with 2, 33 / 36 / 45 with 4, at a costlier setup.
SCHUR_WINDOW = 1


def schur_bandwidth(window: int = SCHUR_WINDOW) -> int:
    """Super-diagonals of :func:`schur_absorption` for clusters of ``window`` first coefficients."""
    return _AX * (window + _NB - 1) - 1


#: Stars whose ``kappa = tr(N_i) tr(B_i^-1)`` (data information times prior-limited variance,
#: a bound on the condition of ``B_i`` that matters here) exceeds this get the orthogonal form
#: of :func:`schur_absorption`: the normal-equation form ``G'G - H' B^-1 H`` loses about
#: ``kappa x 2e-16`` of the star's information to rounding. Under a 1000 mas prior a star
#: seen once or twice has kappa ~ 1e10-1e12 (its parallax and proper motion are known only
#: from the prior), so the loss, ~1e-6 of its ``G'G``, swamps what the knot keeps: at the
#: paper's sizes with 25 FoV transits per knot (771117 knots) the band was not positive
#: definite at coefficient 452453, where the exact pivots fall to 1.5e-6-1.1e-4 of the
#: diagonal, and elsewhere to 1e-9 (docs/notes/table3/prior_1000mas.md). Below 1e6 the loss is < 2e-10 and the
#: faster form is kept (at 3 x 30000 stars with 25 FoV transits per knot: for all but 50
#: stars under sigma_F90, 632 under 10 sigma_F90, 1825 under 1000 mas).
STABLE_ABSORPTION_KAPPA = 1e6


def schur_absorption(blk: StarBlock, prior, batch_stars: int = 4096, window: int = SCHUR_WINDOW,
                      columns: tuple[int, int] | None = None) -> np.ndarray:
    """The in-band part of ``N_as B^-1 N_sa`` (upper band storage, ``L = schur_bandwidth + 1``
    rows): the banded Schur block is ``N_aa`` (:func:`att_band`, prior-independent) minus this.
    ``prior (n, 5)``: the diagonal of the block's stars' ``N_p``.

    Exact form: ``S_B = sum_i G_i' (I - P_i) G_i`` with ``P_i = A_i B_i^-1 A_i'`` per star
    (``G_i`` its attitude rows). Group each star's measurements into clusters whose first
    coefficients ``j0`` lie in one window of ``window`` values (all their attitude
    unknowns then lie in one ``3 (window + 3)``-wide range) and keep only the diagonal
    cluster blocks of ``P_i``: ``S_band = sum_i sum_c G_ic' (I - P_i,cc) G_ic``. As
    ``0 <= P_i <= I``, every ``I - P_i,cc`` is positive semi-definite, so ``S_band`` is
    too, and it is banded. It keeps exactly what makes the plain block preconditioner
    fail with loose priors: a star seen at one or two epochs absorbs the attitude
    signal at those epochs.

    Two forms of a cluster's absorption ``G_c' P_cc G_c``: ``H' B^-1 H`` with ``H = A_c' G_c``
    (most stars), and, for stars above :data:`STABLE_ABSORPTION_KAPPA`, ``G_c'G_c - R22'R22``
    with ``R22`` what Householder reflections of the five source columns leave of
    ``[[A_c, G_c], [A_other, 0], [N_p^1/2, 0]]`` (the cluster's rows, the star's other rows and
    its prior), so that ``G_c'(I - P_cc)G_c = R22'R22`` is formed without squaring ``B_i``'s
    condition and is positive semi-definite whatever the rounding (Golub & Van Loan 2013,
    Matrix Computations, Sect. 5.3: QR against the normal equations).

    ``columns=(lo, hi)``: only the band's columns ``lo .. hi - 1`` (unknowns), as an ``(L, hi -
    lo)`` slab, from the clusters that touch them; each element is the same sum, in the same
    order, as in the whole band (the stars' batches and their clusters' order are kept), so
    slabs put side by side are the whole band bit for bit, and the solver can sum the blocks'
    absorption slab by slab (:mod:`~mcsweep.solver.schur_preconditioner`) without ever holding more
    than one band.
    """
    n_att = _AX * blk.n_coef
    L = schur_bandwidth(window) + 1
    c_lo, c_hi = (0, n_att) if columns is None else (int(columns[0]), int(columns[1]))
    ab = np.zeros((L, c_hi - c_lo))
    scratch = np.zeros(c_hi - c_lo)  # band_scatter's, zero between calls
    prior = np.broadcast_to(np.asarray(prior, dtype=float), (blk.n, _NP))
    ill = ill_conditioned(blk)
    order = _absorption_rows(blk, ill, window, L, c_lo, c_hi)
    star_sorted = blk.star[order]
    for lo in range(0, blk.n, batch_stars):  # bounds temporary memory; fixed order
        hi = min(lo + batch_stars, blk.n)
        sel = order[np.searchsorted(star_sorted, lo):np.searchsorted(star_sorted, hi)]
        if sel.size == 0:
            continue
        star, j0 = blk.star[sel].astype(np.int64), blk.j0[sel].astype(np.int64)
        G = (blk.bval[:, None, sel].astype(float) * att_rows(blk, sel)[None, :, :]).reshape(_AX * _NB, -1)  # (12, m)
        a_all = src_rows(blk, sel)
        jb = (j0 // window) * window
        ill_row = ill[star]
        rows = np.flatnonzero(~ill_row)
        if rows.size:
            _normal_absorption(ab, blk, rows, star, j0, jb, a_all, G, window, L, c_lo, scratch)
        if ill_row.any():
            _orthogonal_absorption(ab, a_all, G, j0 - jb, star - lo, star * blk.n_coef + jb, jb, ill_row,
                                   prior[lo:hi], L, c_lo)
    return ab


def _absorption_rows(blk: StarBlock, ill, window: int, L: int, c_lo: int, c_hi: int) -> np.ndarray:
    """The rows :func:`schur_absorption` visits for the band's columns ``c_lo .. c_hi - 1``, star
    by star, each in time order: those of clusters touching the columns, and every row of an
    ill-conditioned star with such a cluster (its other rows enter the orthogonal form)."""
    base_row = _AX * (blk.j0.astype(np.int64) // window) * window
    touch = (base_row + L > c_lo) & (base_row < c_hi)
    ill_star = ill[blk.star]
    take = touch & ~ill_star
    if ill.any():
        ill_touching = np.zeros(blk.n, dtype=bool)
        ill_touching[blk.star[touch & ill_star]] = True
        take |= ill_touching[blk.star]
    visit = np.flatnonzero(take)
    return visit[np.argsort(blk.star[visit], kind="stable")]  # star by star, each in time order


def _normal_absorption(ab, blk: StarBlock, rows, star, j0, jb, a_all, G, window: int, L: int, c_lo: int,
                       scratch) -> None:
    """The normal-equation form ``H' B^-1 H`` of the absorption of the clusters of a batch's
    ``rows`` (well-conditioned stars), added into the band ``ab`` (:func:`schur_absorption`)."""
    # H[i, c, k] = sum of a_i G_r over cluster k's rows, c = 3 (j0 - jb) + r; structure
    # of arrays (one contiguous vector over clusters per element), as in
    # mcsweep.astrometry.linalg, so every step below is a vector operation. Clusters are
    # runs of equal (star, jb) (``sel`` is in star order, each star's rows in time order).
    key = star[rows] * blk.n_coef + jb[rows]
    new_cluster = np.r_[True, key[1:] != key[:-1]]
    uniq, cl = key[new_cluster], np.cumsum(new_cluster) - 1
    nc = uniq.size
    H = np.zeros((_NP, L, nc))
    for o in range(window):  # rows by offset of their j0 within the window
        at = slice(None) if window == 1 else np.flatnonzero(j0[rows] - jb[rows] == o)
        for i in range(_NP):
            a = a_all[i][rows][at]
            for r in range(_AX * _NB):
                H[i, _AX * o + r] += np.bincount(cl[at], a * G[r][rows][at], minlength=nc)
    Bc = np.ascontiguousarray(blk.binv[uniq // blk.n_coef].transpose(1, 2, 0))  # (5, 5, clusters)
    BH = np.empty_like(H)  # B^-1 H
    for i in range(_NP):
        BH[i] = Bc[i, 0] * H[0]
        for k in range(1, _NP):
            BH[i] += Bc[i, k] * H[k]
    # H' B^-1 H, upper band only, straight into the band storage (compiled: a bincount over
    # all n_att unknowns per element of the band cost ~3 s per block with AGIS's 30 s knots)
    kernel_backend.active().band_scatter(ab, H, BH, _AX * (uniq % blk.n_coef) - c_lo, scratch)


def ill_conditioned(blk: StarBlock) -> np.ndarray:
    """Per star, whether ``kappa = tr(N_i) tr(B_i^-1)`` exceeds :data:`STABLE_ABSORPTION_KAPPA`
    (then :func:`schur_absorption` takes its orthogonal form)."""
    m = blk.t.shape[0]
    w = np.empty(m)  # each row's squared partials, in runs of rows (bounded temporaries)
    for lo in range(0, m, 1 << 16):
        a = src_rows(blk, slice(lo, lo + (1 << 16)))
        w[lo:lo + a.shape[1]] = np.sum(a * a, axis=0)
    info = np.bincount(blk.star, w, minlength=blk.n)  # tr(N_i), each star's rows in time order
    return info * np.trace(blk.binv, axis1=1, axis2=2) > STABLE_ABSORPTION_KAPPA


def _orthogonal_absorption(ab, a_all, G, offset, star, key, jb, ill_row, prior, L, c_lo) -> None:
    """Add the absorption ``G_c'G_c - R22'R22`` of the clusters of rows ``ill_row`` (all of a
    star's rows or none) into ``ab`` (:func:`schur_absorption`, the orthogonal form; compiled:
    :func:`~mcsweep.solver.kernels.orthogonal_absorption`). ``offset``: each row's ``j0``
    within its window; ``star``: within the batch; ``key``: each row's cluster (star x
    n_coef + ``jb``, the first coefficient of its window); ``c_lo``: the unknown of ``ab``'s
    first column."""
    rows = np.flatnonzero(ill_row)
    Gt = np.zeros((rows.size, L))  # each row's attitude partials placed in its cluster's window
    for o in np.unique(offset[rows]):
        at = offset[rows] == o
        Gt[at, _AX * o:_AX * o + _AX * _NB] = G[:, rows[at]].T
    s_first, c_first = (np.flatnonzero(np.r_[True, np.diff(x[rows]) != 0]) for x in (star, key))  # runs of rows
    kernel_backend.active().orthogonal_absorption(ab, a_all[:, rows].T, Gt, prior[star[rows][s_first]],
                                                  np.r_[s_first, rows.size], np.r_[c_first, rows.size],
                                                  _AX * jb[rows][c_first] - c_lo)


def block_setup(blk: StarBlock, h, start=None) -> dict:
    """What the solver needs once per prior from a block, for the measurements ``h (m,)``
    less what the starting attitude ``start (n_coef, 3)`` explains, if given, besides its
    Schur absorption (:func:`schur_absorption`, summed slab by slab).

    Returns a dict of global contributions, ``b_a = A_a' h``, ``hh = h' h``, and per star
    ``b_s = A_s' h`` (n, 5). ``hh`` by numpy's pairwise add-reduce, not ``h @ h``: BLAS
    ``ddot`` rounds differently with the alignment of ``h``, which differs on a Dask worker
    (unpickled) from the driver.
    """
    g = gather(blk)
    if start is not None:
        h = h - att_forward(blk, start, g)
    return {"b_a": att_adjoint(blk, h, g), "hh": float(np.sum(np.multiply(h, h))), "b_s": src_adjoint(blk, h, g)}


# ------------------------------------------------------------------ iteration
def block_precondition_forward(blk: StarBlock, r_s, out=None) -> np.ndarray:
    """The block's part of ``N_as B^-1 r_s`` (n_coef, 3): first sweep of the preconditioner
    (one compiled pass, :func:`~mcsweep.solver.kernels.precondition_forward`), added into
    ``out`` if given (a leaf's sum, :mod:`~mcsweep.solver.reduction`)."""
    return kernel_backend.active().precondition_forward(blk, _binv(blk, r_s), out)


def block_precondition_back(blk: StarBlock, r_s, z_a, ya=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Last sweep of the preconditioner and the data part of ``N z`` for the result.

    Returns ``z_s = B^-1 (r_s - N_sa z_a)`` (n, 5), and ``A' A z`` as (stars (n, 5),
    attitude (n_coef, 3)) (compiled passes, :func:`~mcsweep.solver.kernels.precondition_back`;
    the same products as :func:`att_forward`, :func:`src_adjoint`, :func:`src_forward` and
    :func:`att_adjoint` in sequence); the attitude part added into ``ya`` if given.
    """
    return kernel_backend.active().precondition_back(blk, r_s, z_a, ya)


def block_residuals(blk: StarBlock, h, x_s, x_a) -> np.ndarray:
    """Normalised measurement residuals ``h - A x`` of the block (m,)."""
    g = gather(blk)
    return h - src_forward(blk, x_s, g) - att_forward(blk, x_a, g)


def block_normal_apply(blk: StarBlock, v_s, v_a) -> tuple[np.ndarray, np.ndarray]:
    """Data part of the full normal matrix, ``A' A v``: (stars (n, 5), attitude (n_coef, 3))."""
    g = gather(blk)
    f = src_forward(blk, v_s, g) + att_forward(blk, v_a, g)
    return src_adjoint(blk, f, g), att_adjoint(blk, f, g)
