"""The prior scan's compiled passes: the reduction of each star's normal equations, and the
inside test over the whole prior grid.

:func:`reduce_normals` and :func:`reduce_shared_design` do the reduction of
:mod:`mcsweep.astrometry.prior_scan` (Schur complement of the position block, 3 x 3 Jacobi
eigen-decomposition) for blocks of :data:`REDUCE_BLOCK` stars: every step is one loop over
the block's stars with no branch, so it compiles to SIMD over stars, and the block's
vectors stay in cache. :func:`reduce_shared_design` forms each star's normal equations in
registers, in the loop that takes its Schur complement, from the factored form of stars
observed with one design (:class:`mcsweep.astrometry.shared_design.SharedDesignNormals`): no
normal matrix is written, not even a block's (the sums in the order the explicit matrices
have them, so the outputs are :func:`reduce_normals`' of those, bit for bit;
tests/astrometry/test_shared_design.py).

:func:`inside_flags_grid` evaluates, for every star and every prior t of the grid, the five
quantities ``y_j = base_j + sum_k X_jk w_k`` (position error and covariance,
``w_k = 1 / (lam_k + t)``) and the ellipse test of
:func:`mcsweep.astrometry.confidence.inside_components`, one pass per prior with each
star's quantities in registers; :func:`inside_counts_grid` counts the same tests block by
block of stars, every prior on a block while it is in cache.

Vectorisation. A loop over stars compiles to SIMD only if LLVM can index it without numba's
wrap-around of negative indices (an index from ``range(n)`` is known to be non-negative; a
block's offset is made unsigned, :func:`_column`), with no call in it (a tuple indexed by a
variable is one) and with few enough runtime alias checks (:data:`VECTORISER_MEMORY_CHECKS`).
LLVM's vectoriser remarks (``llvmlite.binding.set_option("", "-pass-remarks-missed=loop-vectorize")``
with ``NUMBA_DEBUGINFO=1``) name the loops that stay scalar and why.

Rounding. Numba compiles without ``fastmath``: LLVM neither reassociates nor contracts
into fused multiply-adds, so the results do not depend on the block size, the machine's
vector width or the order of the stars (tests/astrometry/test_prior_scan.py). The Jacobi
rotation uses ``sqrt(theta^2 + 1)`` where Numerical Recipes writes ``hypot(theta, 1)``:
the same to rounding, and vectorisable; where ``theta^2`` overflows (|theta| > 1e154) the
rotation is the identity to within 1e-154.
"""

from __future__ import annotations

import llvmlite.binding
import numba
import numpy as np

__all__ = ["REDUCE_BLOCK", "COUNT_BLOCK", "JACOBI_SWEEPS", "JACOBI_NEGLIGIBLE", "NULL_PIVOT",
           "VECTORISER_MEMORY_CHECKS", "reduce_normals", "reduce_shared_design", "normal_noise",
           "inside_flags_grid", "inside_counts_grid", "position_statistics_grid"]

_jit = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False)

#: Runtime alias checks LLVM's loop vectoriser may emit for one loop (its default: 128). The loop
#: over stars of :func:`reduce_shared_design` reads ten star vectors and writes some thirty, and
#: needs between 512 and 2000 checks (measured with LLVM's vectoriser remarks); below that it
#: stays scalar, 1.6 x slower. The checks run once per block of stars, not per star. The option
#: is LLVM's, for the whole process: it changes which loops vectorise, never a result (no
#: ``fastmath``: a vectorised loop does each star's operations in the same order).
VECTORISER_MEMORY_CHECKS = 4096
llvmlite.binding.set_option("mcsweep", f"-vectorize-memory-check-threshold={VECTORISER_MEMORY_CHECKS}")

#: Stars per block of the compiled reduction: the block's ~40 vectors stay in L1/L2 cache.
REDUCE_BLOCK = 256
#: Stars per block of the inside counts (:func:`inside_counts_grid`): a block's 24 vectors
#: (200 kB) stay in L2 cache over the whole prior grid.
COUNT_BLOCK = 1024
#: Most cyclic Jacobi sweeps for a 3 x 3 symmetric matrix. Convergence is quadratic
#: after the first sweep (Golub & Van Loan, Matrix Computations, Sect. 8.5.4); 3 x 3
#: matrices reach the rounding level in 4-5 sweeps.
JACOBI_SWEEPS = 8
#: A rotation is skipped where ``|a_pq| <= JACOBI_NEGLIGIBLE * (|a_pp| + |a_qq|)``:
#: two orders of magnitude below the rounding of the diagonal elements, so skipping it
#: changes no eigenvalue or eigenvector beyond rounding.
JACOBI_NEGLIGIBLE = 1e-18
#: An LDL' pivot of a star's Schur complement S at or below this fraction of the normal
#: matrix's diagonal element (C's, not S's: a singular S is all rounding, and its own diagonal
#: would keep it) is a null direction (:func:`_star_noise`); a direction measured with 1e-5 of
#: C's precision is still kept. Where the position block A is ill-conditioned, S's rounding is
#: eps cond(A) of C: the fraction is then NULL_ROUNDING eps cond(A) if larger.
NULL_PIVOT = 1e-10
#: The rounding of S = C - B' A^-1 B, in units of eps cond(A) C (the few dozen roundings of its
#: formation, with margin).
NULL_ROUNDING = 64.0
_EPS = float(np.finfo(np.float64).eps)


@numba.njit(inline="always")
def _givens(cr, sr, x, y, s):
    """Rotate element ``s`` of the pair of rows (or columns) ``x``, ``y`` by (cos, sin) = (cr, sr)."""
    p = x[s]
    q = y[s]
    x[s] = cr * p - sr * q
    y[s] = sr * p + cr * q


@_jit
def _rotate(m, app, aqq, apq, arp, arq, v0p, v1p, v2p, v0q, v1q, v2q):
    """One Jacobi rotation in the (p, q) plane of the first ``m`` stars (Numerical Recipes,
    Sect. 11.1); r is the third index. Returns how many stars needed it."""
    active = 0
    for s in range(m):
        a_pq = apq[s]
        nz = abs(a_pq) > JACOBI_NEGLIGIBLE * (abs(app[s]) + abs(aqq[s]))
        theta = (aqq[s] - app[s]) / (2.0 * (a_pq if nz else 1.0))
        tr = np.copysign(1.0, theta) / (abs(theta) + np.sqrt(theta * theta + 1.0))
        tr = tr if nz else 0.0
        cr = 1.0 / np.sqrt(tr * tr + 1.0)
        sr = tr * cr
        tapq = tr * a_pq
        app[s] = app[s] - tapq
        aqq[s] = aqq[s] + tapq
        apq[s] = 0.0 if nz else a_pq
        _givens(cr, sr, arp, arq, s)
        _givens(cr, sr, v0p, v0q, s)
        _givens(cr, sr, v1p, v1q, s)
        _givens(cr, sr, v2p, v2q, s)
        active += nz
    return active


@numba.njit(inline="always")
def _column(lo, s):
    # Star s of the block at lo as an unsigned index: a signed one may be negative for all
    # LLVM knows, and numba's wrap-around of negative indices then keeps the loop scalar.
    return np.uint64(lo) + np.uint64(s)


@numba.njit(inline="always")
def _position_inverse(n00, n01, n10, n11, pivot):
    """Whether a star's position block A (its normal matrix's first 2 x 2, symmetrised) is
    regular, and A^-1's elements (i0, i1, i2) = (aa, ad, dd); of a singular block, its
    adjugate (finite, unused: the star is not ok)."""
    a11 = n00
    a12 = 0.5 * (n01 + n10)
    a22 = n11
    det = a11 * a22 - a12 * a12
    good = (a11 > 0.0) & (a22 > 0.0) & (det > pivot * a11 * a22) & (abs(det) < np.inf)
    ds = det if good else 1.0
    return good, a22 / ds, -a12 / ds, a11 / ds


@numba.njit(inline="always")
def _inverse_times(i0, i1, i2, b):
    """A^-1 B (2 x 3, row-major) of A^-1's elements and B's (b00, b01, b02, b10, b11, b12)."""
    b00, b01, b02, b10, b11, b12 = b
    return (i0 * b00 + i1 * b10, i0 * b01 + i1 * b11, i0 * b02 + i1 * b12,
            i1 * b00 + i2 * b10, i1 * b01 + i2 * b11, i1 * b02 + i2 * b12)


@numba.njit(inline="always")
def _schur_star(s, k, nn, bb, r_, pivot, w, x0, ainv, ok):
    """Star ``s`` of a block (output column ``k``, unsigned: see :func:`_column`): the position
    block's inverse, x0, and into the scratch ``w`` the scaled Schur complement T, r and
    A^-1 B (the first step of :func:`_reduce_block`); ``nij``: the elements of its normal
    matrix, ``bi`` of its right-hand side."""
    n00, n01, n10, n11, n02, n03, n04, n12, n13, n14, n22, n33, n44, n23, n32, n24, n42, n34, n43 = nn
    b0, b1, b2, b3, b4 = bb
    sc1 = r_
    sc2 = r_ * r_
    good, i0, i1, i2 = _position_inverse(n00, n01, n10, n11, pivot)
    b00 = n02
    b01 = n03
    b02 = n04
    b10 = n12
    b11 = n13
    b12 = n14
    # A^-1 B (2 x 3) and x0 = A^-1 b_p
    q00, q01, q02, q10, q11, q12 = _inverse_times(i0, i1, i2, (b00, b01, b02, b10, b11, b12))
    x_a = i0 * b0 + i1 * b1
    x_d = i1 * b0 + i2 * b1
    # T = W3^-1/2 S W3^-1/2, S = C - B' A^-1 B symmetrised, W3^-1/2 = diag(1, R, R)
    s00 = n22 - (b00 * q00 + b10 * q10)
    s11 = n33 - (b01 * q01 + b11 * q11)
    s22 = n44 - (b02 * q02 + b12 * q12)
    s01 = 0.5 * ((n23 - (b00 * q01 + b10 * q11)) + (n32 - (b01 * q00 + b11 * q10)))
    s02 = 0.5 * ((n24 - (b00 * q02 + b10 * q12)) + (n42 - (b02 * q00 + b12 * q10)))
    s12 = 0.5 * ((n34 - (b01 * q02 + b11 * q12)) + (n43 - (b02 * q01 + b12 * q11)))
    # NaN of a singular star kept out of the rotations
    w[0, s] = s00 if good else 0.0
    w[1, s] = s11 * sc2 if good else 0.0
    w[2, s] = s22 * sc2 if good else 0.0
    w[3, s] = s01 * sc1 if good else 0.0
    w[4, s] = s02 * sc1 if good else 0.0
    w[5, s] = s12 * sc2 if good else 0.0
    w[21, s] = b2 - (b00 * x_a + b10 * x_d)
    w[22, s] = b3 - (b01 * x_a + b11 * x_d)
    w[23, s] = b4 - (b02 * x_a + b12 * x_d)
    w[15, s] = q00
    w[16, s] = q01
    w[17, s] = q02
    w[18, s] = q10
    w[19, s] = q11
    w[20, s] = q12
    w[6, s] = 1.0
    w[7, s] = 0.0
    w[8, s] = 0.0
    w[9, s] = 0.0
    w[10, s] = 1.0
    w[11, s] = 0.0
    w[12, s] = 0.0
    w[13, s] = 0.0
    w[14, s] = 1.0
    x0[0, k] = x_a
    x0[1, k] = x_d
    ainv[0, k] = i0
    ainv[1, k] = i1
    ainv[2, k] = i2
    ok[k] = good


@_jit
def _reduce_block(N, b, m, r_, pivot, w, lo, x0, ainv, g, c, lam, ok):
    """The reduction of the first ``m`` stars of ``N (5, 5, B)``, ``b (5, B)`` into the output
    arrays at ``lo``; ``w (24, B)``: scratch."""
    for s in range(m):
        nn = (N[0, 0, s], N[0, 1, s], N[1, 0, s], N[1, 1, s], N[0, 2, s], N[0, 3, s], N[0, 4, s], N[1, 2, s],
              N[1, 3, s], N[1, 4, s], N[2, 2, s], N[3, 3, s], N[4, 4, s], N[2, 3, s], N[3, 2, s], N[2, 4, s],
              N[4, 2, s], N[3, 4, s], N[4, 3, s])
        _schur_star(s, _column(lo, s), nn, (b[0, s], b[1, s], b[2, s], b[3, s], b[4, s]), r_, pivot, w, x0, ainv,
                    ok)
    _eigen_block(m, r_, w, lo, g, c, lam)


@_jit
def _eigen_block(m, r_, w, lo, g, c, lam):
    """The Jacobi eigen-decomposition of the block's T (scratch ``w`` as :func:`_schur_star`
    leaves it) and the outputs G, c and lam at ``lo``."""
    t00, t11, t22, t01, t02, t12 = w[0], w[1], w[2], w[3], w[4], w[5]
    v00, v01, v02, v10, v11, v12, v20, v21, v22 = w[6], w[7], w[8], w[9], w[10], w[11], w[12], w[13], w[14]
    h00, h01, h02, h10, h11, h12 = w[15], w[16], w[17], w[18], w[19], w[20]
    r0, r1, r2 = w[21], w[22], w[23]
    for _ in range(JACOBI_SWEEPS):
        active = _rotate(m, t00, t11, t01, t02, t12, v00, v10, v20, v01, v11, v21)   # (p, q) = (0, 1)
        active += _rotate(m, t00, t22, t02, t01, t12, v00, v10, v20, v02, v12, v22)  # (0, 2)
        active += _rotate(m, t11, t22, t12, t01, t02, v01, v11, v21, v02, v12, v22)  # (1, 2)
        if active == 0:
            break
    for s in range(m):
        # U = diag(1, R, R) V; G = A^-1 B U; c = U' r
        u00 = v00[s]
        u01 = v01[s]
        u02 = v02[s]
        u10 = v10[s] * r_
        u11 = v11[s] * r_
        u12 = v12[s] * r_
        u20 = v20[s] * r_
        u21 = v21[s] * r_
        u22 = v22[s] * r_
        k = _column(lo, s)
        lam[0, k] = t00[s]
        lam[1, k] = t11[s]
        lam[2, k] = t22[s]
        g[0, 0, k] = h00[s] * u00 + h01[s] * u10 + h02[s] * u20
        g[0, 1, k] = h00[s] * u01 + h01[s] * u11 + h02[s] * u21
        g[0, 2, k] = h00[s] * u02 + h01[s] * u12 + h02[s] * u22
        g[1, 0, k] = h10[s] * u00 + h11[s] * u10 + h12[s] * u20
        g[1, 1, k] = h10[s] * u01 + h11[s] * u11 + h12[s] * u21
        g[1, 2, k] = h10[s] * u02 + h11[s] * u12 + h12[s] * u22
        c[0, k] = u00 * r0[s] + u10 * r1[s] + u20 * r2[s]
        c[1, k] = u01 * r0[s] + u11 * r1[s] + u21 * r2[s]
        c[2, k] = u02 * r0[s] + u12 * r1[s] + u22 * r2[s]


@_jit
def reduce_normals(N, b, r_, pivot, x0, ainv, g, c, lam, ok):
    """The prior-scan reduction of star-last normal equations ``N (5, 5, n)``, ``b (5, n)``
    into ``x0 (2, n)``, ``ainv (3, n)``, ``g (2, 3, n)``, ``c (3, n)``, ``lam (3, n)``,
    ``ok (n,)`` (:class:`mcsweep.astrometry.prior_scan.PriorScan`); ``pivot``: the
    singularity tolerance of the position block."""
    n = b.shape[1]
    Nb = np.empty((5, 5, REDUCE_BLOCK))
    bb = np.empty((5, REDUCE_BLOCK))
    w = np.empty((24, REDUCE_BLOCK))
    for lo in range(0, n, REDUCE_BLOCK):
        m = min(REDUCE_BLOCK, n - lo)
        Nb[:, :, :m] = N[:, :, lo:lo + m]
        bb[:, :m] = b[:, lo:lo + m]
        _reduce_block(Nb, bb, m, r_, pivot, w, lo, x0, ainv, g, c, lam, ok)


@numba.njit(inline="always")
def _upper(nu, q):
    """Block ``q``'s matrix ``nu[q]`` as its upper triangle, the 15-tuple (00, 01, 11, 02, 03,
    04, 12, 13, 14, 22, 33, 44, 23, 24, 34) that the per-star helpers index (loads the loop
    over stars does not repeat)."""
    m = nu[q]
    return (m[0, 0], m[0, 1], m[1, 1], m[0, 2], m[0, 3], m[0, 4], m[1, 2], m[1, 3], m[1, 4], m[2, 2], m[3, 3],
            m[4, 4], m[2, 3], m[2, 4], m[3, 4])


@numba.njit(inline="always")
def _element(a0, a1, w0sq, w1sq, two):
    # An element of a star's normal matrix from the blocks' elements a0 and a1, summed over the
    # blocks from zero as reduce_normals' callers form it (the same value bit for bit, signed
    # zeros included). The callers index the blocks' tuples with literals: an index in a
    # variable compiles to a call, which keeps the loop over stars scalar.
    acc = 0.0 + a0 * w0sq
    return acc + a1 * w1sq if two else acc


@numba.njit(inline="always")
def _signal(a, b, x, w0sq, w1sq, two):
    # An element of a star's noise-free right-hand side N x: per block (a, then b), a row's
    # parallax and proper-motion elements times the truth x.
    acc = 0.0 + (a[0] * x[0] + a[1] * x[1] + a[2] * x[2]) * w0sq
    if two:
        acc = acc + (b[0] * x[0] + b[1] * x[1] + b[2] * x[2]) * w1sq
    return acc


@numba.njit(inline="always")
def _pivot(d, floor):
    # A pivot of the Schur complement's LDL' at or below ``floor`` (NULL_PIVOT's rule) is a
    # null direction (one or two transits): zero, no noise along it.
    return d if d > floor else 0.0


@numba.njit(inline="always")
def _semidefinite_noise(s00, s11, s22, s01, s02, s12, c0, c1, c2, za, zb, zc):
    """``L sqrt(D) z`` with ``S = L D L'`` (S positive semi-definite, 3 x 3): Gaussian noise of
    covariance S from three standard normals. Diagonal pivoting, the largest remaining diagonal
    element first, so every multiplier is at most 1 and a null direction's pivot is rounding
    of the order of the largest, and dropped (:func:`_pivot`, against ``c``: the normal
    matrix's diagonal elements times NULL_PIVOT's fraction); the first pivot takes ``za``, the
    second ``zb``."""
    # first pivot p: the order (p, then the other two in index order)
    p1 = (s11 > s00) & (s11 >= s22)
    p2 = (s22 > s00) & (s22 > s11)
    m00 = s22 if p2 else (s11 if p1 else s00)
    m11 = s00 if (p1 or p2) else s11
    m22 = s11 if p2 else s22
    m01 = s02 if p2 else s01
    m02 = s12 if (p1 or p2) else s02
    m12 = s01 if p2 else (s02 if p1 else s12)
    k0 = c2 if p2 else (c1 if p1 else c0)
    k1 = c0 if (p1 or p2) else c1
    k2 = c1 if p2 else c2
    d0 = _pivot(m00, k0)
    f10 = m01 / d0 if d0 > 0.0 else 0.0
    f20 = m02 / d0 if d0 > 0.0 else 0.0
    t11 = m11 - f10 * m01
    t22 = m22 - f20 * m02
    t12 = m12 - f20 * m01
    # second pivot: the larger of the two left (swap them if it is the last)
    sw = t22 > t11
    u11 = t22 if sw else t11
    u22 = t11 if sw else t22
    g10 = f20 if sw else f10
    g20 = f10 if sw else f20
    d1 = _pivot(u11, k2 if sw else k1)
    f21 = t12 / d1 if d1 > 0.0 else 0.0
    d2 = _pivot(u22 - f21 * t12, k1 if sw else k2)
    e0 = np.sqrt(d0) * za
    e1 = np.sqrt(d1) * zb
    y1 = g10 * e0 + e1
    y2 = (g20 * e0 + f21 * e1) + np.sqrt(d2) * zc
    # back to the order of the pivots, then of S
    v1 = y2 if sw else y1
    v2 = y1 if sw else y2
    r0 = v1 if (p1 or p2) else e0
    r1 = e0 if p1 else (v2 if p2 else v1)
    r2 = e0 if p2 else v2
    return r0, r1, r2


@numba.njit(inline="always")
def _star_noise(nn, z, pivot):
    """The noise of a star's right-hand side, Gaussian of covariance N, from five standard
    normals ``z`` (module :mod:`~mcsweep.astrometry.shared_design`); ``nn``: N's upper
    triangle in the order of :func:`_upper`. Zero where the position block is singular."""
    n00, n01, n11, n02, n03, n04, n12, n13, n14, n22, n33, n44, n23, n24, n34 = nn
    z0, z1, z2, z3, z4 = z
    good, i0, i1, i2 = _position_inverse(n00, n01, n01, n11, pivot)
    a11 = n00 if good else 1.0
    # position block: n_p = L_A z[:2], L_A L_A' = A
    l11 = np.sqrt(a11)
    p0 = l11 * z0
    p1 = (n01 / l11) * z0 + np.sqrt((n00 * n11 - n01 * n01 if good else 1.0) / a11) * z1
    # A^-1 B, and the Schur complement S = C - B' A^-1 B
    q00, q01, q02, q10, q11, q12 = _inverse_times(i0, i1, i2, (n02, n03, n04, n12, n13, n14))
    s00 = n22 - (n02 * q00 + n12 * q10)
    s11 = n33 - (n03 * q01 + n13 * q11)
    s22 = n44 - (n04 * q02 + n14 * q12)
    s01 = n23 - (n02 * q01 + n12 * q11)
    s02 = n24 - (n02 * q02 + n12 * q12)
    s12 = n34 - (n03 * q02 + n13 * q12)
    # The noise of r = b_q - B' A^-1 b_p, independent of n_p, with covariance S; (a11 + a22)^2
    # / det A bounds cond(A) from above
    trace = n00 + n11
    rounding = NULL_ROUNDING * _EPS * (trace * (trace / (n00 * n11 - n01 * n01 if good else 1.0)))
    null = rounding if rounding > NULL_PIVOT else NULL_PIVOT  # max(), without its call
    e0, e1, e2 = _semidefinite_noise(s00, s11, s22, s01, s02, s12, null * n22, null * n33, null * n44, z2, z3, z4)
    # n_q = B' A^-1 n_p + r's noise
    y0 = i0 * p0 + i1 * p1
    y1 = i1 * p0 + i2 * p1
    m2 = (n02 * y0 + n12 * y1) + e0
    m3 = (n03 * y0 + n13 * y1) + e1
    m4 = (n04 * y0 + n14 * y1) + e2
    return (p0 if good else 0.0, p1 if good else 0.0, m2 if good else 0.0, m3 if good else 0.0,
            m4 if good else 0.0)


@_jit
def normal_noise(N, z, pivot, out):
    """Fill ``out (5, n)`` with each star's right-hand-side noise of covariance ``N (5, 5, n)``
    from the standard normals ``z (5, n)``, as :func:`reduce_shared_design` adds it."""
    for s in range(z.shape[1]):
        nn = (N[0, 0, s], N[0, 1, s], N[1, 1, s], N[0, 2, s], N[0, 3, s], N[0, 4, s], N[1, 2, s], N[1, 3, s],
              N[1, 4, s], N[2, 2, s], N[3, 3, s], N[4, 4, s], N[2, 3, s], N[2, 4, s], N[3, 4, s])
        m0, m1, m2, m3, m4 = _star_noise(nn, (z[0, s], z[1, s], z[2, s], z[3, s], z[4, s]), pivot)
        out[0, s] = m0
        out[1, s] = m1
        out[2, s] = m2
        out[3, s] = m3
        out[4, s] = m4


@_jit
def reduce_shared_design(unit, weight, truth, noise, r_, pivot, x0, ainv, g, c, lam, ok):
    """:func:`reduce_normals` of stars observed with one design up to per-star weights.

    ``unit (n_blk, k, 5)``: the rows of each block at unit weight (AL, then AC if used:
    ``n_blk`` is 1 or 2), the design or its triangular factor; ``weight (n_blk, n)``: each
    star's 1 / sigma per block; ``truth (3, n)``: parallax and proper motion (the position's
    truth is zero); ``noise (5, n)``: standard normals. Star i's normal matrix (Eq. 2) is
    ``N_i = sum_blk w_blk,i^2 U_blk' U_blk`` and its right-hand side (Eq. 3) ``N_i x_i``
    plus the noise of :func:`normal_noise`, both formed star by star in registers on the way
    into the Schur step: the outputs are :func:`reduce_normals`' of those sums, bit for bit,
    and no normal matrix is written.
    """
    n_blk, k = unit.shape[0], unit.shape[1]
    n = truth.shape[1]
    two = n_blk == 2
    nu = np.zeros((2, 5, 5))
    for q in range(n_blk):
        for i in range(5):
            for j in range(5):
                acc = 0.0
                for r in range(k):
                    acc += unit[q, r, i] * unit[q, r, j]
                nu[q, i, j] = acc
    w = np.empty((24, REDUCE_BLOCK))
    e0 = _upper(nu, 0)
    e1 = _upper(nu, 1)
    # a load the loop does unconditionally (a conditional one would keep it scalar); unused
    # with one block
    weight1 = weight[1] if two else weight[0]
    for lo in range(0, n, REDUCE_BLOCK):
        m = min(REDUCE_BLOCK, n - lo)
        for s in range(m):
            k = _column(lo, s)
            w0 = weight[0, k]
            w1 = weight1[k] if two else 0.0
            w0sq = w0 * w0
            w1sq = w1 * w1
            x = (truth[0, k], truth[1, k], truth[2, k])
            n00 = _element(e0[0], e1[0], w0sq, w1sq, two)
            n01 = _element(e0[1], e1[1], w0sq, w1sq, two)
            n11 = _element(e0[2], e1[2], w0sq, w1sq, two)
            n02 = _element(e0[3], e1[3], w0sq, w1sq, two)
            n03 = _element(e0[4], e1[4], w0sq, w1sq, two)
            n04 = _element(e0[5], e1[5], w0sq, w1sq, two)
            n12 = _element(e0[6], e1[6], w0sq, w1sq, two)
            n13 = _element(e0[7], e1[7], w0sq, w1sq, two)
            n14 = _element(e0[8], e1[8], w0sq, w1sq, two)
            n22 = _element(e0[9], e1[9], w0sq, w1sq, two)
            n33 = _element(e0[10], e1[10], w0sq, w1sq, two)
            n44 = _element(e0[11], e1[11], w0sq, w1sq, two)
            n23 = _element(e0[12], e1[12], w0sq, w1sq, two)
            n24 = _element(e0[13], e1[13], w0sq, w1sq, two)
            n34 = _element(e0[14], e1[14], w0sq, w1sq, two)
            upper = (n00, n01, n11, n02, n03, n04, n12, n13, n14, n22, n33, n44, n23, n24, n34)
            m0, m1, m2, m3, m4 = _star_noise(upper, (noise[0, k], noise[1, k], noise[2, k], noise[3, k], noise[4, k]),
                                             pivot)
            b0 = _signal((e0[3], e0[4], e0[5]), (e1[3], e1[4], e1[5]), x, w0sq, w1sq, two) + m0
            b1 = _signal((e0[6], e0[7], e0[8]), (e1[6], e1[7], e1[8]), x, w0sq, w1sq, two) + m1
            b2 = _signal((e0[9], e0[12], e0[13]), (e1[9], e1[12], e1[13]), x, w0sq, w1sq, two) + m2
            b3 = _signal((e0[12], e0[10], e0[14]), (e1[12], e1[10], e1[14]), x, w0sq, w1sq, two) + m3
            b4 = _signal((e0[13], e0[14], e0[11]), (e1[13], e1[14], e1[11]), x, w0sq, w1sq, two) + m4
            # nu is symmetric bit for bit (each element the same products in the same order)
            nn = (n00, n01, n01, n11, n02, n03, n04, n12, n13, n14, n22, n33, n44, n23, n23, n24, n24, n34, n34)
            _schur_star(s, k, nn, (b0, b1, b2, b3, b4), r_, pivot, w, x0, ainv, ok)
        _eigen_block(m, r_, w, lo, g, c, lam)


@numba.njit(inline="always")
def _x_terms(g, c, n):
    # X[k] = (-(g0 c_k), -(g1 c_k), g0 g0, g0 g1, g1 g1) as in the numpy arithmetic.
    X = np.empty((3, 5, n))
    for k in range(3):
        for s in range(n):
            g0 = g[0, k, s]
            g1 = g[1, k, s]
            X[k, 0, s] = -(g0 * c[k, s])
            X[k, 1, s] = -(g1 * c[k, s])
            X[k, 2, s] = g0 * g0
            X[k, 3, s] = g0 * g1
            X[k, 4, s] = g1 * g1
    return X


@numba.njit(inline="always")
def _star_test(X, x0, ainv, lam, worst, s, t, k_threshold):
    """(valid, inside) of star ``s`` at prior ``t``."""
    w0 = 1.0 / (lam[0, s] + t)
    w1 = 1.0 / (lam[1, s] + t)
    w2 = 1.0 / (lam[2, s] + t)
    dx = ((X[0, 0, s] * w0 + x0[0, s]) + X[1, 0, s] * w1) + X[2, 0, s] * w2
    dy = ((X[0, 1, s] * w0 + x0[1, s]) + X[1, 1, s] * w1) + X[2, 1, s] * w2
    caa = ((X[0, 2, s] * w0 + ainv[0, s]) + X[1, 2, s] * w1) + X[2, 2, s] * w2
    cad = ((X[0, 3, s] * w0 + ainv[1, s]) + X[1, 3, s] * w1) + X[2, 3, s] * w2
    cdd = ((X[0, 4, s] * w0 + ainv[2, s]) + X[1, 4, s] * w1) + X[2, 4, s] * w2
    t1 = (cdd * dx - (cad * dy) * 2.0) * dx
    t1 = t1 + (caa * dy) * dy
    det = caa * cdd - cad * cad
    q = t1 / det
    # |q| < inf is isfinite(q): false for NaN and for +-inf.
    ok = (det > 0.0) & (caa > 0.0) & (np.abs(q) < np.inf) & (worst[s] + t > 0.0)
    return ok, ok & (q < k_threshold)


@_jit
def inside_flags_grid(x0, ainv, g, c, lam, worst, ts, k_threshold, inside, valid):
    """Fill ``inside`` and ``valid`` (m, n) for the priors ``ts`` (m,) (prior-scan arrays, star-last).

    ``worst`` (n,): the smallest eigenvalue, -inf for a star whose position block is
    singular: no solution where ``worst + t <= 0`` (the rule of ``PriorScan._bad``).
    Priors outside, stars inside and no branch in the inner loop: it compiles to SIMD
    over stars (2.5 x the star-outer loop, measured on 20 000 stars x 41 priors).
    """
    n = worst.shape[0]
    X = _x_terms(g, c, n)
    for i in range(ts.shape[0]):
        t = ts[i]
        ins_row = inside[i]
        val_row = valid[i]
        for s in range(n):
            ok, ins = _star_test(X, x0, ainv, lam, worst, s, t, k_threshold)
            val_row[s] = ok
            ins_row[s] = ins


@_jit
def inside_counts_grid(x0, ainv, g, c, lam, worst, ts, k_threshold, n_inside, n_valid, key_inside, key_valid):
    """The counts of :func:`inside_flags_grid` per prior, ``n_inside`` and ``n_valid`` (m,),
    without the (m, n) flags; with ``key_inside`` and ``key_valid`` of length n (m <= 64),
    also each star's flags over the grid as the bits of one integer (bit i: prior i).

    Stars in blocks of :data:`COUNT_BLOCK`, every prior on a block while its ~200 kB are in
    cache, and the two forms separate loops: with the keys' test inside the loop over stars
    LLVM vectorised only the keyed form, and the counts alone ran 2.5-3 x slower than in a
    loop of their own (measured on 20 000 stars x 41 priors)."""
    n = worst.shape[0]
    X = _x_terms(g, c, n)
    keys = key_inside.shape[0] == n
    if keys:
        for s in range(n):
            key_inside[s] = 0
            key_valid[s] = 0
    for i in range(ts.shape[0]):
        n_inside[i] = 0
        n_valid[i] = 0
    for lo in range(0, n, COUNT_BLOCK):
        hi = min(n, lo + COUNT_BLOCK)
        for i in range(ts.shape[0]):
            if keys:
                bit = np.uint64(1) << np.uint64(i)
                n_in, n_ok = _block_counts_and_keys(X, x0, ainv, lam, worst, lo, hi, ts[i], k_threshold, bit,
                                                    key_inside, key_valid)
            else:
                n_in, n_ok = _block_counts(X, x0, ainv, lam, worst, lo, hi, ts[i], k_threshold)
            n_inside[i] += n_in
            n_valid[i] += n_ok


@_jit
def _block_counts(X, x0, ainv, lam, worst, lo, hi, t, k_threshold):
    n_in = 0
    n_ok = 0
    for j in range(hi - lo):
        s = _column(lo, j)
        ok, ins = _star_test(X, x0, ainv, lam, worst, s, t, k_threshold)
        n_ok += ok
        n_in += ins
    return n_in, n_ok


@_jit
def _block_counts_and_keys(X, x0, ainv, lam, worst, lo, hi, t, k_threshold, bit, key_inside, key_valid):
    # _block_counts' loop that also writes the keys: kept apart, not merged behind a flag,
    # because LLVM vectorised only one form of the merged loop (inside_counts_grid)
    n_in = 0
    n_ok = 0
    for j in range(hi - lo):
        s = _column(lo, j)
        ok, ins = _star_test(X, x0, ainv, lam, worst, s, t, k_threshold)
        n_ok += ok
        n_in += ins
        key_valid[s] |= bit * np.uint64(ok)
        key_inside[s] |= bit * np.uint64(ins)
    return n_in, n_ok


@_jit
def position_statistics_grid(x0, ainv, g, c, lam, worst, ts, k_threshold, err, semi_major):
    """Fill ``err`` and ``semi_major`` (m, n): each star's actual position error and the
    semi-major axis of its P ellipse (``k_threshold``: the chi-square quantile) at the priors
    ``ts`` (m,); NaN where the star has no solution (``worst``, as in :func:`inside_flags_grid`).

    The arithmetic of :meth:`mcsweep.astrometry.prior_scan.PriorScan.position` followed by
    ``hypot`` of the position and :func:`mcsweep.astrometry.confidence.ellipse_semi_axes`,
    operation for operation, so the values are the numpy path's bit for bit
    (tests/astrometry/test_prior_scan.py), in one pass with no (n, 2, 2) arrays.
    """
    n = worst.shape[0]
    nan = np.nan
    for i in range(ts.shape[0]):
        t = ts[i]
        for s in range(n):
            w0 = 1.0 / (lam[0, s] + t)
            w1 = 1.0 / (lam[1, s] + t)
            w2 = 1.0 / (lam[2, s] + t)
            wc0 = w0 * c[0, s]
            wc1 = w1 * c[1, s]
            wc2 = w2 * c[2, s]
            d0 = x0[0, s] - ((g[0, 0, s] * wc0 + g[0, 1, s] * wc1) + g[0, 2, s] * wc2)
            d1 = x0[1, s] - ((g[1, 0, s] * wc0 + g[1, 1, s] * wc1) + g[1, 2, s] * wc2)
            wg0 = w0 * g[0, 0, s]
            wg1 = w1 * g[0, 1, s]
            wg2 = w2 * g[0, 2, s]
            a = ainv[0, s] + ((wg0 * g[0, 0, s] + wg1 * g[0, 1, s]) + wg2 * g[0, 2, s])
            b = ainv[1, s] + ((wg0 * g[1, 0, s] + wg1 * g[1, 1, s]) + wg2 * g[1, 2, s])
            e = ainv[2, s] + ((w0 * (g[1, 0, s] * g[1, 0, s]) + w1 * (g[1, 1, s] * g[1, 1, s]))
                              + w2 * (g[1, 2, s] * g[1, 2, s]))
            good = worst[s] + t > 0.0
            d0 = d0 if good else nan
            d1 = d1 if good else nan
            a = a if good else nan
            b = b if good else nan
            e = e if good else nan
            # ellipse_semi_axes: b is the mean of the two off-diagonal elements (equal here)
            b = 0.5 * (b + b)
            lam_max = 0.5 * (a + e) + np.hypot(0.5 * (a - e), b)
            err[i, s] = np.hypot(d0, d1)
            semi_major[i, s] = np.sqrt(k_threshold * lam_max)
