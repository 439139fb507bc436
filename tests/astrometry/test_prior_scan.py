"""The prior scan against the 5 x 5 Cholesky solver and against an exact rational solve."""

from fractions import Fraction

import numpy as np
import pytest

from mcsweep.astrometry.confidence import ellipse_semi_axes
from mcsweep.astrometry.prior_scan import prior_scan
from mcsweep.astrometry.solve import solve_with_prior

#: Agreement of the scan with the direct solver (relative to the largest element of
#: each star's position or covariance), wherever the problem allows it (below).
RTOL_SCAN = 1e-10
#: Scaled condition number of N0 + N_p up to which two backward-stable methods must
#: agree to RTOL_SCAN: their forward errors are ~ kappa * eps (1e5 * 2.2e-16 = 2e-11).
KAPPA_MAX = 1e5
#: Beyond that (loose priors with 1-2 transits, kappa up to ~1e10) no float64 method
#: is accurate to 1e-10; the scan must then be within kappa * eps * FORWARD_FACTOR of
#: the exact solution. FORWARD_FACTOR covers the few-dozen roundings of either path.
FORWARD_FACTOR = 1e3
EPS = np.finfo(float).eps
PRIORS = np.geomspace(0.01, 1000.0, 9)


def _normals(rng, n, rows, *, singular_pos=False):
    """Normal equations of ``rows`` random measurements per star (rank <= rows)."""
    a = rng.normal(size=(n, rows, 5)) * np.array([10.0, 10.0, 8.0, 3.0, 3.0])
    if singular_pos:
        a[:, :, 1] = 0.7 * a[:, :, 0]  # position block of rank 1
    h = rng.normal(size=(n, rows)) + a @ np.array([0.0, 0.0, 2.0, 15.0, -8.0])
    return np.einsum("nri,nrj->nij", a, a), np.einsum("nri,nr->ni", a, h)


def _rel(new, ref, floor=None):
    """Largest error of each star relative to its largest element, shape (n,).

    ``floor`` (n,): a smallest scale. Positions are compared relative to the larger of
    their size and their standard deviation: a position error much smaller than its
    own uncertainty is a difference of large terms, and what the fraction inside
    uses is ``dpos / sigma`` (Sect. 2.4).
    """
    n = len(ref)
    if n == 0:
        return np.zeros(0)
    scale = np.abs(ref).reshape(n, -1).max(axis=1, initial=0.0)
    if floor is not None:
        scale = np.maximum(scale, floor)
    return np.abs(new - ref).reshape(n, -1).max(axis=1, initial=0.0) / scale


@pytest.mark.parametrize("rows", [2, 3, 4, 12])
def test_scan_equals_direct_solver(rows):
    rng = np.random.default_rng(rows)
    n0, b0 = _normals(rng, 400, rows)
    scan = prior_scan(n0, b0, 10.0)
    for sigma in PRIORS:
        sol = solve_with_prior(n0, b0, sigma, 10.0, with_condition=True)
        dpos, cov = scan.position(sigma)
        np.testing.assert_array_equal(np.isfinite(dpos[:, 0]), sol.ok)
        use = sol.ok & (sol.condition <= KAPPA_MAX)
        sd = np.sqrt(np.maximum(sol.cov[use, 0, 0], sol.cov[use, 1, 1]))
        assert _rel(dpos[use], sol.x[use, :2], sd).max(initial=0.0) <= RTOL_SCAN
        assert _rel(cov[use], sol.cov[use, :2, :2]).max(initial=0.0) <= RTOL_SCAN
    # The singular N0 (rank 1-4 < 5) must have reached the tested range for some prior.
    assert (solve_with_prior(n0, b0, PRIORS[0], 10.0, with_condition=True).condition <= KAPPA_MAX).any()


def test_singular_position_block_has_no_solution():
    n0, b0 = _normals(np.random.default_rng(3), 50, 6, singular_pos=True)
    dpos, cov = prior_scan(n0, b0).position(1.0)
    assert not solve_with_prior(n0, b0, 1.0).ok.any()
    assert np.isnan(dpos).all() and np.isnan(cov).all()


def _exact(N, b, sigma, R):
    """Position and its covariance of (N + N_p) x = b in exact rational arithmetic."""
    w = [0.0, 0.0, sigma**-2, (R * sigma) ** -2, (R * sigma) ** -2]
    m = [[Fraction(float(N[r, c])) + (Fraction(w[r]) if r == c else 0) for c in range(5)]
         + [Fraction(float(b[r]))] + [Fraction(int(r == k)) for k in range(2)] for r in range(5)]
    for c in range(5):
        m[c] = [v / m[c][c] for v in m[c]]
        for r in range(5):
            if r != c and m[r][c] != 0:
                f = m[r][c]
                m[r] = [x - f * y for x, y in zip(m[r], m[c])]
    return np.array([float(m[0][5]), float(m[1][5])]), np.array([[float(m[i][6 + j]) for j in range(2)]
                                                                 for i in range(2)])


@pytest.mark.parametrize("rows", [2, 3, 12])
def test_scan_against_exact_solution(rows):
    n0, b0 = _normals(np.random.default_rng(10 + rows), 6, rows)
    scan = prior_scan(n0, b0, 10.0)
    for sigma in PRIORS[::2]:
        kappa = solve_with_prior(n0, b0, sigma, 10.0, with_condition=True).condition
        dpos, cov = scan.position(sigma)
        for i in range(len(n0)):
            x_ref, c_ref = _exact(n0[i], b0[i], sigma, 10.0)
            tol = max(RTOL_SCAN, FORWARD_FACTOR * kappa[i] * EPS)
            sd = np.sqrt(c_ref.diagonal().max())
            assert _rel(dpos[i:i + 1], x_ref[None], sd)[0] <= tol
            assert _rel(cov[i:i + 1], c_ref[None])[0] <= tol


def test_batching_does_not_change_results():
    n0, b0 = _normals(np.random.default_rng(5), 300, 3)
    whole = prior_scan(n0, b0).position(3.0)
    parts = [prior_scan(n0[sl], b0[sl]).position(3.0) for sl in (slice(0, 117), slice(117, 300))]
    np.testing.assert_array_equal(whole[0], np.concatenate([p[0] for p in parts]))
    np.testing.assert_array_equal(whole[1], np.concatenate([p[1] for p in parts]))


@pytest.mark.parametrize("rows", [2, 3, 12])
def test_inside_flags_equal_the_confidence_rule_on_the_direct_solution(rows):
    # The fused test of every prior against confidence.inside / mahalanobis_sq applied to
    # the 5 x 5 solver's solution; singular stars and the NaN rule included.
    from mcsweep.astrometry.confidence import chi2_threshold, inside, mahalanobis_sq

    # Two float paths to the Mahalanobis distance: a star within this relative distance of
    # the threshold may fall on either side of it; every other flag must agree exactly.
    rtol_threshold = 1e-8
    k = chi2_threshold(0.9, 2)

    rng = np.random.default_rng(40 + rows)
    n0, b0 = _normals(rng, 700, rows)
    n0[:5] = 0.0  # no position: no confidence region at any prior
    b0[:5] = 0.0
    priors = np.geomspace(0.01, 1000.0, 17)
    ins, val = prior_scan(n0, b0, 10.0).inside_flags(priors, 0.9)
    for i, sigma in enumerate(priors):
        sol = solve_with_prior(n0, b0, sigma, 10.0)
        dpos, cov = np.ascontiguousarray(sol.x[:, :2]), np.ascontiguousarray(sol.cov[:, :2, :2])
        q = mahalanobis_sq(dpos, cov)
        np.testing.assert_array_equal(val[i], np.isfinite(q))
        clear = ~np.isfinite(q) | (np.abs(q - k) > rtol_threshold * k)
        assert clear.mean() > 0.99
        np.testing.assert_array_equal(ins[i][clear], inside(dpos, cov, 0.9)[clear])
    assert not val[:, :5].any()


def _numpy_inside_flags(scan, priors, P):
    """The inside test as numpy vector operations, the arithmetic the compiled kernel must
    reproduce bit for bit: y = X0 w0 + base + X1 w1 + X2 w2, then inside_components."""
    from mcsweep.astrometry.confidence import inside_components
    from mcsweep.astrometry.solve import prior_diagonal

    ts = prior_diagonal(np.asarray(priors, float), scan.ratio_R)[:, 2]
    g, c = scan.g, scan.c
    base = np.stack([scan.x0[0], scan.x0[1], scan.ainv[0], scan.ainv[1], scan.ainv[2]])
    X = np.stack([np.stack([-(g[0, k] * c[k]), -(g[1, k] * c[k]), g[0, k] * g[0, k], g[0, k] * g[1, k],
                            g[1, k] * g[1, k]]) for k in range(3)])
    worst = np.where(scan.ok, scan.lam.min(axis=0), -np.inf)
    inside, valid = [], []
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for t in ts:
            w = 1.0 / (scan.lam + t)
            y = X[0] * w[0]
            y += base
            y = y + X[1] * w[1]
            y = y + X[2] * w[2]
            ins, val = inside_components(*y, P)
            bad = ~(worst + t > 0.0)
            inside.append(ins & ~bad)
            valid.append(val & ~bad)
    return np.array(inside), np.array(valid)


def _grid_scan(seed, n, rows):
    """A prior scan of ``n`` random stars, the first five without a position, and the sweep's
    grid of 41 priors."""
    n0, b0 = _normals(np.random.default_rng(seed), n, rows)
    n0[:5] = 0.0
    b0[:5] = 0.0
    return prior_scan(n0, b0, 10.0), np.geomspace(0.01, 1000.0, 41)


@pytest.mark.parametrize("rows", [2, 3, 12])
def test_compiled_inside_flags_are_the_numpy_arithmetic_bit_for_bit(rows):
    scan, priors = _grid_scan(70 + rows, 3000, rows)
    got = scan.inside_flags(priors, 0.9)
    ref = _numpy_inside_flags(scan, priors, 0.9)
    np.testing.assert_array_equal(got[0], ref[0])
    np.testing.assert_array_equal(got[1], ref[1])



@pytest.mark.parametrize("rows", [2, 3, 12])
def test_compiled_position_statistics_are_the_numpy_arithmetic_bit_for_bit(rows):
    # The sweep's results promise: the compiled pass gives the error and semi-major axis that
    # hypot of PriorScan.position and confidence.ellipse_semi_axes give, bit for bit (NaN
    # where a star has no solution: the first five stars).
    scan, priors = _grid_scan(110 + rows, 3000, rows)
    err, semi = scan.position_statistics(priors, 0.9)
    for i, p in enumerate(priors):
        dpos, cov2 = scan.position(p)
        np.testing.assert_array_equal(err[i], np.hypot(dpos[:, 0], dpos[:, 1]))
        with np.errstate(invalid="ignore"):
            np.testing.assert_array_equal(semi[i], ellipse_semi_axes(cov2, 0.9)[0])
    assert np.isnan(err[:, :5]).all() and np.isfinite(err[:, 5:]).all()


@pytest.mark.parametrize("rows", [2, 3, 12])
def test_inside_counts_and_keys_are_the_flags(rows):
    # The counts per prior and each star's flags as integer bits, without the (m, n) flags.
    scan, priors = _grid_scan(90 + rows, 2000, rows)
    inside, valid = scan.inside_flags(priors, 0.9)
    n_in, n_val, (k_in, k_val) = scan.inside_counts(priors, 0.9, keys=True)
    np.testing.assert_array_equal(n_in, inside.sum(axis=1))
    np.testing.assert_array_equal(n_val, valid.sum(axis=1))
    bits = np.uint64(1) << np.arange(41, dtype=np.uint64)
    np.testing.assert_array_equal((k_in[None, :] & bits[:, None]) != 0, inside)
    np.testing.assert_array_equal((k_val[None, :] & bits[:, None]) != 0, valid)
    again = scan.inside_counts(priors, 0.9)
    np.testing.assert_array_equal(again[0], n_in)
    assert again[2] is None
    with pytest.raises(ValueError, match="at most 64"):
        scan.inside_counts(np.geomspace(0.01, 1000.0, 65), 0.9, keys=True)


def test_compiled_reduction_does_not_depend_on_the_block_of_a_star():
    # Blocks of REDUCE_BLOCK stars: a star's result is the same wherever it falls.
    from mcsweep.astrometry.scan_kernel import REDUCE_BLOCK

    n0, b0 = _normals(np.random.default_rng(8), 3 * REDUCE_BLOCK + 17, 4)
    whole = prior_scan(n0, b0)
    shifted = prior_scan(n0[37:], b0[37:])
    for name in ("x0", "ainv", "g", "c", "lam", "ok"):
        np.testing.assert_array_equal(getattr(whole, name)[..., 37:], getattr(shifted, name))
