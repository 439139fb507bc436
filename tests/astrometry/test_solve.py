"""Solutions of Sect. 2 against closed forms, Monte Carlo and the paper's statements."""

import numpy as np
import pytest
from scipy import stats

from mcsweep.astrometry.design import design_matrix, reference_epoch, years_since
from mcsweep.astrometry.measurements import simulate
from mcsweep.astrometry.noise import NoiseModel
from mcsweep.astrometry.solve import (
    DEFAULT_RATIO_R,
    normal_equations,
    solve_no_prior,
    solve_position_only,
    solve_with_prior,
)
from mcsweep.errors import UserInputError
from mcsweep.scanning.ephemeris import gaia_position_au

#: Appendix A formula (Eq. A.2) versus the general solver with a prior (solve_with_prior), relative.
APPENDIX_RTOL = 1e-9
#: Recovery of the true parameters from noiseless data, mas or mas/yr.
NOISELESS_ATOL = 1e-9
#: Smallest acceptable KS p-value for the chi-square tests (fixed seeds).
KS_MIN_PVALUE = 0.01
#: Largest acceptable Monte Carlo deviation, in standard errors of the estimate.
MC_MAX_Z = 5.0


def _geometry(table1, groups, *, use_ac=True, g_mag=15.0, n=1):
    """Design matrix of n identical stars observed in the given Table 1 groups."""
    sel = np.isin(table1["group"], groups)
    jd = np.broadcast_to(table1["tcb_jd"][sel], (n, sel.sum()))
    t_yr = years_since(jd, reference_epoch(jd))
    psi = np.broadcast_to(table1["psi_deg"][sel], jd.shape)
    obs = gaia_position_au(jd)
    noise = NoiseModel(use_ac=use_ac)
    sig_al, sig_ac = noise.design_sigmas(np.full(n, g_mag))
    ra, dec = np.full(n, table1["ra_deg"]), np.full(n, table1["dec_deg"])
    return design_matrix(ra, dec, t_yr, psi, obs, sigma_al_mas=sig_al, sigma_ac_mas=sig_ac)


def _random_stars(rng, n, k, *, span_yr=1.5):
    """Stars at random places, each with its own k transits (random times and angles)."""
    jd = 2456960.0 + 365.25 * span_yr * rng.uniform(size=(n, k))
    ra, dec = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))
    psi = rng.uniform(0, 360, (n, k))
    t_yr = years_since(jd, reference_epoch(jd))
    g = rng.uniform(10, 20, n)
    sig_al, sig_ac = NoiseModel().design_sigmas(g)
    return design_matrix(ra, dec, t_yr, psi, gaia_position_au(jd), sigma_al_mas=sig_al, sigma_ac_mas=sig_ac)


# --- Appendix A ---------------------------------------------------------------------

def _appendix_normal_matrix(sigma_delta, sigma_plx, rho):
    """N0 of the Appendix (delta, parallax block; prior term left out), embedded in 5 x 5.

    The block is the Appendix expression with sigma_plx,p -> infinity. The other three
    parameters are uncorrelated with unit information, so they do not interact.
    """
    n = rho.size
    N0 = np.zeros((n, 5, 5))
    N0[:, 0, 0] = N0[:, 3, 3] = N0[:, 4, 4] = 1.0
    f = 1.0 / (1.0 - rho**2)
    N0[:, 1, 1] = f / sigma_delta**2
    N0[:, 2, 2] = f / sigma_plx**2
    N0[:, 1, 2] = N0[:, 2, 1] = -f * rho / (sigma_delta * sigma_plx)
    return N0


def test_appendix_formula_reproduced_by_general_solver():
    sigma_delta, sigma_plx = 0.7, 1.3  # mas
    rho_grid = np.array([-0.999, -0.9, -0.5, 0.0, 0.3, 0.7, 0.95, 0.999])
    ratio_grid = np.logspace(-4, 4, 17)  # sigma_plx,p / sigma_plx
    rho, ratio = (a.ravel() for a in np.meshgrid(rho_grid, ratio_grid))
    N0 = _appendix_normal_matrix(sigma_delta, sigma_plx, rho)
    sol = solve_with_prior(N0, np.zeros((rho.size, 5)), ratio * sigma_plx)
    expected = sigma_delta * np.sqrt(1.0 - rho**2 / (1.0 + ratio**2))  # Eq. A.2
    np.testing.assert_allclose(np.sqrt(sol.cov[:, 1, 1]), expected, rtol=APPENDIX_RTOL)


def test_appendix_limits_tight_and_loose_prior():
    sigma_delta, sigma_plx = 0.7, 1.3
    rho = np.array([-0.9, 0.0, 0.5, 0.99])
    N0 = _appendix_normal_matrix(sigma_delta, sigma_plx, rho)
    tight = solve_with_prior(N0, np.zeros((4, 5)), 1e-6 * sigma_plx)
    loose = solve_with_prior(N0, np.zeros((4, 5)), 1e6 * sigma_plx)
    np.testing.assert_allclose(np.sqrt(tight.cov[:, 1, 1]), sigma_delta * np.sqrt(1 - rho**2), rtol=APPENDIX_RTOL)
    np.testing.assert_allclose(np.sqrt(loose.cov[:, 1, 1]), sigma_delta, rtol=APPENDIX_RTOL)


# --- Eqs. 11-13 and 18 -----------------------------------------------------------------

@pytest.mark.parametrize("ratio_R", [DEFAULT_RATIO_R, 3.0])
def test_posterior_covariance_inverse_is_n0_plus_prior(table1, ratio_R):
    A = _geometry(table1, [1, 2, 3])
    N0, b0 = normal_equations(A, np.zeros(A.shape[:2]))
    sigma_p = 0.8
    sol = solve_with_prior(N0, b0, sigma_p, ratio_R)
    Np = np.linalg.inv(sol.cov[0]) - N0[0]
    expected = np.diag([0.0, 0.0, sigma_p**-2, (ratio_R * sigma_p) ** -2, (ratio_R * sigma_p) ** -2])
    np.testing.assert_allclose(Np, expected, rtol=0, atol=1e-8 * np.abs(N0[0]).max())


def test_normal_equations_are_a_transpose_a(table1):
    rng = np.random.default_rng(5)
    A = _random_stars(rng, 40, 7)
    h = rng.normal(size=A.shape[:2])
    N0, b0 = normal_equations(A, h)
    np.testing.assert_allclose(N0, np.array([a.T @ a for a in A]), rtol=1e-13)
    np.testing.assert_allclose(b0, np.array([a.T @ v for a, v in zip(A, h)]), rtol=1e-12, atol=1e-12)


def test_noiseless_many_transits_recover_true_parameters(table1):
    A = _geometry(table1, list(range(1, 9)), n=3)
    x_true = np.array([[0.0, 0.0, 4.2, 31.0, -17.5], [0.0, 0.0, 0.05, -2.0, 0.3], [1.0, -2.0, 12.0, 0.0, 88.0]])
    h = np.einsum("nmj,nj->nm", A, x_true)
    sol = solve_no_prior(*normal_equations(A, h))
    assert sol.ok.all()
    np.testing.assert_allclose(sol.x, x_true, rtol=0, atol=NOISELESS_ATOL)


def test_normalised_errors_follow_chi2_with_5_dof():
    rng = np.random.default_rng(20150821)
    n = 4000
    A = _random_stars(rng, n, 12)
    x_true = np.column_stack([np.zeros((n, 2)), rng.uniform(0, 5, n), rng.normal(0, 20, (n, 2))])
    N0, b0 = normal_equations(A, simulate(A, x_true, rng))
    sol = solve_no_prior(N0, b0)
    assert sol.ok.all()
    d = sol.x - x_true
    q = np.einsum("ni,nij,nj->n", d, N0, d)
    assert stats.kstest(q, stats.chi2(5).cdf).pvalue > KS_MIN_PVALUE
    # The statistic must be able to fail: with covariances off by 20 % it does.
    assert stats.kstest(1.2 * q, stats.chi2(5).cdf).pvalue < KS_MIN_PVALUE


def test_prior_solution_is_calibrated_when_truth_is_drawn_from_the_prior(table1):
    """x_true ~ prior  =>  (x - x_true)' (N0 + Np) (x - x_true) ~ chi2(5) (Bayes, Eq. 10)."""
    rng = np.random.default_rng(7)
    n, sigma_p, R = 5000, 2.0, DEFAULT_RATIO_R
    A = _geometry(table1, [1, 2], n=n)  # two distinct transits: the prior matters
    x_true = np.column_stack([np.zeros((n, 2)), rng.normal(0, sigma_p, n), rng.normal(0, R * sigma_p, (n, 2))])
    N0, b0 = normal_equations(A, simulate(A, x_true, rng))
    sol = solve_with_prior(N0, b0, sigma_p, R)
    d = sol.x - x_true
    Np = np.diag([0, 0, sigma_p**-2, (R * sigma_p) ** -2, (R * sigma_p) ** -2])
    q = np.einsum("ni,nij,nj->n", d, N0 + Np, d)
    assert stats.kstest(q, stats.chi2(5).cdf).pvalue > KS_MIN_PVALUE


def _mc_check(samples, mean, cov):
    m = samples.shape[0]
    z_mean = (samples.mean(axis=0) - mean) / np.sqrt(np.diag(cov) / m)
    s = np.cov(samples, rowvar=False)
    se = np.sqrt((np.outer(np.diag(cov), np.diag(cov)) + cov**2) / m)  # std error of a sample covariance
    assert np.abs(z_mean).max() < MC_MAX_Z
    assert np.abs((s - cov) / se).max() < MC_MAX_Z


def test_scatter_of_solutions_matches_predicted_covariance(table1):
    """gala-style: 2^14 seeded realisations of one star versus the analytic covariance."""
    m = 2**14
    rng = np.random.default_rng(np.random.SeedSequence(2015, spawn_key=(1,)))
    A = _geometry(table1, [1, 2, 3, 4], n=m)
    x_true = np.array([0.0, 0.0, 1.5, 5.0, -3.0])
    N0, b0 = normal_equations(A, simulate(A, x_true, rng))
    C0 = np.linalg.inv(N0[0])

    free = solve_no_prior(N0, b0)
    _mc_check(free.x, x_true, C0)  # unbiased, covariance C0 = N0^-1 (Sect. 2.3)

    sigma_p = 1.0
    prior = solve_with_prior(N0, b0, sigma_p)
    C = prior.cov[0]
    np.testing.assert_allclose(C, np.linalg.inv(N0[0] + np.diag([0, 0, 1, 0.01, 0.01])), rtol=1e-10)
    # Frequentist view of the Bayesian estimate x = C b0: mean C N0 x_true, scatter C N0 C.
    _mc_check(prior.x, C @ N0[0] @ x_true, C @ N0[0] @ C)


def test_loose_prior_leaves_a_well_observed_star_unchanged(table1):
    rng = np.random.default_rng(9)
    A = _geometry(table1, list(range(1, 9)), n=200)
    x_true = np.array([0.0, 0.0, 3.0, 12.0, -4.0])
    N0, b0 = normal_equations(A, simulate(A, x_true, rng))
    free = solve_no_prior(N0, b0)
    loose = solve_with_prior(N0, b0, 1e6)
    sigma = np.sqrt(np.einsum("nii->ni", free.cov))
    assert np.abs((loose.x - free.x) / sigma).max() < 1e-6
    np.testing.assert_allclose(loose.cov, free.cov, rtol=1e-6)


def test_single_transit_prior_gives_unique_solution_no_prior_flags_it(table1):
    sel = table1["group"] == 1
    A = _geometry(table1, [1])[:, [0, int(sel.sum())], :]  # one FoV transit: its AL and AC rows
    assert A.shape == (1, 2, 5)
    h = np.array([[0.3, -1.1]])
    N0, b0 = normal_equations(A, h)
    with_prior = solve_with_prior(N0, b0, 1.0)
    assert with_prior.ok.all() and np.all(np.isfinite(with_prior.x)) and np.all(np.isfinite(with_prior.cov))
    assert np.linalg.eigvalsh(with_prior.cov[0]).min() > 0
    # The measurements are fitted exactly (2 data, the prior fixes the rest).
    np.testing.assert_allclose(A[0] @ with_prior.x[0], h[0], rtol=1e-6)
    without = solve_no_prior(N0, b0)
    assert not without.ok[0] and np.all(np.isnan(without.x)) and np.all(np.isnan(without.cov))


def test_default_condition_limit_follows_the_paper_sect_3_3(table1):
    """Two distinct transits never suffice; three do if AL and AC are both used."""
    cases = {((1, 2), True): False, ((1, 8), True): False, ((1, 2, 3), True): True,
             ((1, 2, 3), False): False, (tuple(range(1, 9)), False): True}
    for (groups, use_ac), expect_ok in cases.items():
        A = _geometry(table1, list(groups), use_ac=use_ac)
        sol = solve_no_prior(*normal_equations(A, np.zeros(A.shape[:2])))
        assert bool(sol.ok[0]) is expect_ok, (groups, use_ac, sol.condition[0])
        with_prior = solve_with_prior(*normal_equations(A, np.zeros(A.shape[:2])), 1.0)
        assert with_prior.ok[0]


def test_position_only_is_the_tight_prior_limit(table1):
    rng = np.random.default_rng(12)
    A = _geometry(table1, [1, 2, 3], n=50)
    x_true = np.array([0.0, 0.0, 2.0, 10.0, 5.0])
    N0, b0 = normal_equations(A, simulate(A, x_true, rng))
    pos = solve_position_only(N0, b0)
    np.testing.assert_allclose(pos.cov[:, :2, :2], np.linalg.inv(N0[:, :2, :2]), rtol=1e-12)
    np.testing.assert_allclose(pos.x[:, :2], np.einsum("nij,nj->ni", np.linalg.inv(N0[:, :2, :2]), b0[:, :2]),
                               rtol=1e-10)
    np.testing.assert_array_equal(pos.x[:, 2:], 0.0)
    np.testing.assert_array_equal(pos.cov[:, 2:, :], 0.0)
    tight = solve_with_prior(N0, b0, 1e-7)
    np.testing.assert_allclose(tight.x[:, :2], pos.x[:, :2], rtol=1e-6)
    np.testing.assert_allclose(tight.cov[:, :2, :2], pos.cov[:, :2, :2], rtol=1e-6)


def test_per_star_prior_equals_separate_scalar_solutions(table1):
    rng = np.random.default_rng(13)
    A = _random_stars(rng, 6, 4)
    N0, b0 = normal_equations(A, rng.normal(size=A.shape[:2]))
    sigmas = np.array([0.01, 0.3, 1.0, 4.0, 50.0, 1e3])
    batch = solve_with_prior(N0, b0, sigmas, ratio_R=np.full(6, 7.0))
    for i, s in enumerate(sigmas):
        one = solve_with_prior(N0[i:i + 1], b0[i:i + 1], s, ratio_R=7.0)
        np.testing.assert_allclose(batch.x[i], one.x[0], rtol=1e-12)
        np.testing.assert_allclose(batch.cov[i], one.cov[0], rtol=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda N0, b0: solve_with_prior(N0, b0, 0.0), "sigma_plx_prior_mas"),
    (lambda N0, b0: solve_with_prior(N0, b0, np.nan), "sigma_plx_prior_mas"),
    (lambda N0, b0: solve_with_prior(N0, b0, 1.0, ratio_R=-10.0), "ratio_R"),
    (lambda N0, b0: solve_no_prior(N0, b0, max_condition=0.5), "max_condition"),
])
def test_rejects_bad_options(call, match):
    N0, b0 = np.eye(5)[None], np.zeros((1, 5))
    with pytest.raises(UserInputError, match=match):
        call(N0, b0)
