"""Compiled per-star loops of the galaxy model's draw: absolute magnitudes from the luminosity
functions and the intrinsic colours.

Each loop does, star by star, the arithmetic of the numpy passes it replaces, operation for
operation (``np.interp`` as numpy computes it: the interval by bisection, the slope
``(fp[j+1] - fp[j]) / (xp[j+1] - xp[j])``, then ``slope * (x - xp[j]) + fp[j]``, with numpy's
rules at the ends, at a node and for a NaN), compiled without ``fastmath`` so nothing is
reassociated or fused: the stars drawn are the same bit for bit
(tests/population/test_draw_kernel.py). A star's component picks its row of the tables, so
no sort or mask per component is needed. Trigonometric and logarithmic steps stay in numpy,
whose SIMD routines round differently from a compiled loop's libm calls.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["interp", "absolute_magnitudes", "intrinsic_colours"]

_jit = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False)


@numba.njit(inline="always")
def _last_node_at_or_below(x, xp):
    """The last index j with ``xp[j] <= x``, for ``xp`` sorted (ties allowed) and
    ``xp[0] <= x``: a bisection whose step is a select, not a branch (the table's nodes are
    read in an order the branch predictor cannot learn; the index found is the same)."""
    base = 0
    size = xp.shape[0]
    while size > 1:
        half = size >> 1
        base = base + half if xp[base + half] <= x else base
        size -= half
    return base


@numba.njit(inline="always")
def interp(x, xp, fp, step=0.0):
    """``np.interp(x, xp, fp)`` of one value, for ``xp`` sorted (ties allowed) with at least
    two nodes, as every table of the model is (numpy treats a single node apart). ``step`` > 0:
    the nodes are about evenly spaced by it, and the interval is found from it and checked
    against the nodes (the same interval as numpy's bisection, in two or three reads)."""
    n = xp.shape[0]
    if np.isnan(x):
        return x
    if x > xp[n - 1]:
        return fp[n - 1]
    if x < xp[0]:
        return fp[0]
    if step > 0.0:
        j = min(max(np.intp((x - xp[0]) / step), 0), n - 1)
        while j > 0 and xp[j] > x:
            j -= 1
        while j < n - 1 and xp[j + 1] <= x:
            j += 1
    else:
        j = _last_node_at_or_below(x, xp)
    if j == n - 1 or xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    y = slope * (x - xp[j]) + fp[j]
    if np.isnan(y):  # numpy's fallback: from the other node, then the flat value
        y = slope * (x - xp[j + 1]) + fp[j + 1]
        if np.isnan(y) and fp[j] == fp[j + 1]:
            y = fp[j]
    return y


@_jit
def absolute_magnitudes(k, mu, a_g, u, g_min, g_max, mg, cdf, out):
    """Fill ``out`` with each star's M_G: its component's luminosity function ``cdf[k]`` (on
    the nodes ``mg``) restricted to the apparent range [g_min, g_max) at distance modulus
    ``mu`` and extinction ``a_g``, inverted at the uniform number ``u``."""
    # the nodes' mean spacing: an evenly spaced table's interval in two or three reads (interp)
    step = (mg[mg.shape[0] - 1] - mg[0]) / (mg.shape[0] - 1)
    for s in range(out.shape[0]):
        row = cdf[k[s]]
        off = mu[s] + a_g[s]
        c_lo = interp(g_min - off, mg, row, step)
        c_hi = interp(g_max - off, mg, row, step)
        out[s] = interp(c_lo + u[s] * (c_hi - c_lo), row, mg)


@_jit
def intrinsic_colours(k, m_g, u, mg, density, shift, seq_mv, seq_mg, seq_c, giant_q, giant_mg, n_levels,
                      g_minus_v, subgiant_bp_rp, colour, part):
    """Fill ``colour`` and ``part`` with each star's (BP - RP)_0 and part of the HR diagram
    (:meth:`mcsweep.population.galaxy.colours.ColourTable.intrinsic`, module notes there).

    ``density (n_comp, 4, len(mg) - 1)``: the parts' densities (dwarfs, evolved giants,
    main-sequence stars of the giant bins, subgiants); ``seq_*``: the dwarf sequence;
    ``giant_q (n_comp, len(giant_mg), n_levels)``: the evolved giants' colour quantiles at
    ``n_levels`` evenly spaced levels.
    """
    n_bins = mg.shape[0] - 1
    step = giant_mg[1] - giant_mg[0]
    for s in range(colour.shape[0]):
        m = m_g[s]
        kk = k[s]
        # the bin of m: the last node <= m (NaN after every node, as numpy sorts it), kept
        # within the table
        if np.isnan(m):
            last = mg.shape[0] - 1
        elif m < mg[0]:
            last = -1
        else:
            last = _last_node_at_or_below(m, mg)
        i = min(max(last, 0), n_bins - 1)
        w0 = density[kk, 0, i]
        w1 = density[kk, 1, i]
        c0 = w0
        c1 = c0 + w1
        c2 = c1 + density[kk, 2, i]
        c3 = c2 + density[kk, 3, i]
        x = u[s] * c3
        p = (x >= c0) + (x >= c1) + (x >= c2) + (x >= c3)
        p = min(p, 3) if c3 > 0 else 0
        part[s] = p
        if p == 0:
            colour[s] = interp(m + shift[kk], seq_mg, seq_c)
        elif p == 1:
            node = np.rint((m - giant_mg[0]) / step)
            node_i = min(max(np.intp(node), 0), giant_mg.shape[0] - 1)
            level = (x - c0) / w1
            xl = min(max(level, 0.0), 1.0) * (n_levels - 1)
            j = min(np.intp(xl), n_levels - 2)
            f = xl - j
            colour[s] = giant_q[kk, node_i, j] * (1.0 - f) + giant_q[kk, node_i, j + 1] * f
        elif p == 2:
            colour[s] = interp(m - g_minus_v, seq_mv, seq_c)
        else:
            colour[s] = subgiant_bp_rp
