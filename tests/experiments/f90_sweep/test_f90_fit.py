"""The Eq. 14-17 fit against synthetic sigma_F90 generated from the paper's formula."""

import numpy as np
import pandas as pd
import pytest

from mcsweep.experiments.f90_sweep.fit import PAPER_COEFFICIENTS, fit_all

COEF_TOL = 1e-8  # dex per unit power of G: exact recovery up to rounding


def _healpix48_galactic():
    from astropy_healpix import HEALPix
    from astropy.coordinates import Galactic

    c = HEALPix(nside=2, order="nested", frame=Galactic()).healpix_to_skycoord(np.arange(48))
    return c.l.deg, c.b.deg


def _synthetic(coefs):
    l_deg, b_deg = _healpix48_galactic()
    rows = []
    for g0 in range(6, 20):
        g = g0 + 0.5
        # Eqs. 14-17 written out by hand (independent of mcsweep.experiments.f90_sweep.fit.evaluate_formula).
        s0 = coefs["s0"][0] + coefs["s0"][1] * g + coefs["s0"][2] * g**2
        s1 = coefs["s1"][0] + coefs["s1"][1] * g + coefs["s1"][2] * g**2 + coefs["s1"][3] * g**3
        s2 = coefs["s2"][0] + coefs["s2"][1] * g
        logs = s0 + s1 * np.abs(np.sin(np.radians(b_deg))) + s2 * np.cos(np.radians(b_deg)) * np.cos(np.radians(l_deg))
        for l, b, ls in zip(l_deg, b_deg, logs):
            rows.append(dict(l_deg=l, b_deg=b, g_min=float(g0), g_max=g0 + 1.0, sigma_f90_mas=10**ls, f90_flag="ok"))
    return pd.DataFrame(rows)


@pytest.mark.parametrize("coefs", [
    PAPER_COEFFICIENTS,
    {"s0": (1.9, -0.21, 0.005), "s1": (0.2, -0.07, 0.012, -0.0004), "s2": (0.05, -0.004)},
])
def test_fit_recovers_known_coefficients(coefs):
    fit = fit_all(_synthetic(coefs))
    for name, values in coefs.items():
        assert np.allclose(fit.fitted[name], values, rtol=0, atol=COEF_TOL), name
    assert fit.rms.loc[fit.rms["g_bin"] == "all", "n_cells"].item() == 48 * 14
    if coefs is PAPER_COEFFICIENTS:
        assert np.allclose(fit.coefficients["difference"], 0, atol=COEF_TOL)
        assert fit.rms["rms_diff_dex"].max() < 1e-9
    assert set(fit.coefficients["term"]) == {"s0_c0", "s0_c1", "s0_c2", "s1_c0", "s1_c1", "s1_c2", "s1_c3",
                                             "s2_c0", "s2_c1"}


def test_flagged_cells_are_not_fitted_but_are_compared():
    df = _synthetic(PAPER_COEFFICIENTS)
    df.loc[:9, "f90_flag"] = "never_reached"
    df.loc[:9, "sigma_f90_mas"] = np.nan
    fit = fit_all(df)
    assert np.allclose(fit.fitted["s0"], PAPER_COEFFICIENTS["s0"], atol=COEF_TOL)
    assert len(fit.compared) == len(df)
    assert fit.rms.loc[fit.rms["g_bin"] == "all", "n_cells"].item() == len(df) - 10


def test_paper_formula_value_by_hand():
    # G = 15, (l, b) = (0, 0): s0 = 2.187 - 3.8205 + 1.43595 = -0.19755; s2 = 0.031 - 0.093 = -0.062
    # log10 sigma = -0.19755 - 0.062 = -0.25955 -> 0.54996 mas
    df = pd.DataFrame([dict(l_deg=0.0, b_deg=0.0, g_min=14.5, g_max=15.5, sigma_f90_mas=1.0, f90_flag="ok")])
    from mcsweep.experiments.f90_sweep.fit import compare_cells

    out = compare_cells(df, PAPER_COEFFICIENTS)
    assert out["paper_sigma_f90_mas"].item() == pytest.approx(10**-0.25955, rel=1e-9)


#: Noise added to synthetic log10 sigma_F90 (dex) for the interval-coverage test; over
#: N_NOISY_RUNS independent runs the 16-84 % interval must contain the true coefficient
#: in 68 % of cases within 3 binomial sigma (pooled over the 9 coefficients).
NOISE_DEX = 0.05
N_NOISY_RUNS = 6


def test_fit_intervals_cover_the_true_coefficients():
    rng = np.random.default_rng(7)
    hits = total = 0
    for _ in range(N_NOISY_RUNS):
        cells = _synthetic(PAPER_COEFFICIENTS)
        cells["sigma_f90_mas"] *= 10 ** rng.normal(0, NOISE_DEX, len(cells))
        table = fit_all(cells).coefficients
        assert (table["fitted_lo"] <= table["fitted"]).all() and (table["fitted"] <= table["fitted_hi"]).all()
        hits += int(table["paper_inside"].sum())
        total += len(table)
    tol = 3 * np.sqrt(0.68 * 0.32 / total)
    assert abs(hits / total - 0.68) <= tol, (hits, total)
