"""Fit of the paper's all-sky approximation to simulated sigma_F90 values.

Two least-squares steps, as in Sect. 3.4: per G bin over the directions,
``log10 sigma_F90 = s0 + s1 |sin b| + s2 cos b cos l`` (Eq. 14); then the coefficients
against G with the polynomial degrees of Eqs. 15-17 (2, 3 and 1). G of a bin is its
centre. The comparison with the paper evaluates Eqs. 14-17 at each cell's (l, b, G).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..prior import PAPER_COEFFICIENTS, sigma_from_coefficients

__all__ = [
    "POLY_DEGREES",
    "PAPER_COEFFICIENTS",
    "direction_design",
    "fit_direction_terms",
    "fit_polynomials",
    "evaluate_formula",
    "coefficient_table",
    "compare_cells",
    "rms_table",
    "FitResult",
    "fit_all",
]

#: Polynomial degree in G of s0, s1, s2 (Eqs. 15-17).
POLY_DEGREES = {"s0": 2, "s1": 3, "s2": 1}

def direction_design(l_deg, b_deg) -> np.ndarray:
    """Columns of Eq. 14: 1, |sin b|, cos b cos l."""
    l_rad, b_rad = np.radians(l_deg), np.radians(b_deg)
    return np.column_stack([np.ones_like(l_rad), np.abs(np.sin(b_rad)), np.cos(b_rad) * np.cos(l_rad)])


def fit_direction_terms(f90: pd.DataFrame) -> pd.DataFrame:
    """Eq. 14 per G bin: columns g, s0, s1, s2, n_cells, rms_dex (fit residual)."""
    rows = []
    for (g0, g1), grp in f90.groupby(["g_min", "g_max"], sort=True):
        y = np.log10(grp["sigma_f90_mas"].to_numpy(float))
        a = direction_design(grp["l_deg"].to_numpy(float), grp["b_deg"].to_numpy(float))
        if len(grp) < 3 or np.linalg.matrix_rank(a) < 3:
            rows.append(dict(g_min=g0, g_max=g1, g=(g0 + g1) / 2, s0=np.nan, s1=np.nan, s2=np.nan,
                             n_cells=len(grp), rms_dex=np.nan))
            continue
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        resid = y - a @ coef
        rows.append(dict(g_min=g0, g_max=g1, g=(g0 + g1) / 2, s0=coef[0], s1=coef[1], s2=coef[2],
                         n_cells=len(grp), rms_dex=float(np.sqrt(np.mean(resid**2)))))
    return pd.DataFrame(rows)


def fit_polynomials(terms: pd.DataFrame) -> dict[str, np.ndarray]:
    """Eqs. 15-17: polynomial coefficients (increasing power of G) of s0, s1, s2."""
    ok = terms.dropna(subset=["s0", "s1", "s2"])
    out = {}
    for name, deg in POLY_DEGREES.items():
        if len(ok) <= deg:
            out[name] = np.full(deg + 1, np.nan)
        else:
            out[name] = np.polynomial.polynomial.polyfit(ok["g"].to_numpy(float), ok[name].to_numpy(float), deg)
    return out


def evaluate_formula(coefficients, l_deg, b_deg, g) -> np.ndarray:
    """sigma_F90 [mas] from Eqs. 14-17 with the given coefficients (no clamping in G).

    NaN where a polynomial could not be fitted (fewer G bins than its degree + 1).
    """
    if not all(np.all(np.isfinite(np.asarray(coefficients[k], float))) for k in ("s0", "s1", "s2")):
        return np.full(np.broadcast(np.asarray(l_deg), np.asarray(b_deg), np.asarray(g)).shape, np.nan)
    return sigma_from_coefficients(l_deg, b_deg, g, coefficients)


def coefficient_table(fitted: dict[str, np.ndarray]) -> pd.DataFrame:
    rows = []
    for name in ("s0", "s1", "s2"):
        for power, paper in enumerate(PAPER_COEFFICIENTS[name]):
            ours = float(fitted[name][power])
            rows.append(dict(term=f"{name}_c{power}", fitted=ours, paper=paper, difference=ours - paper))
    return pd.DataFrame(rows)


def compare_cells(f90: pd.DataFrame, fitted: dict[str, np.ndarray]) -> pd.DataFrame:
    """Per cell: our sigma_F90, the paper's formula, our fitted formula, differences in dex."""
    g = (f90["g_min"].to_numpy(float) + f90["g_max"].to_numpy(float)) / 2
    l_deg, b_deg = f90["l_deg"].to_numpy(float), f90["b_deg"].to_numpy(float)
    out = f90.copy()
    out["g"] = g
    out["paper_sigma_f90_mas"] = evaluate_formula(PAPER_COEFFICIENTS, l_deg, b_deg, g)
    out["fitted_sigma_f90_mas"] = evaluate_formula(fitted, l_deg, b_deg, g)
    with np.errstate(divide="ignore", invalid="ignore"):
        out["diff_dex"] = np.log10(out["sigma_f90_mas"] / out["paper_sigma_f90_mas"])
    return out


def rms_table(compared: pd.DataFrame) -> pd.DataFrame:
    """RMS of log10(ours / paper) per G bin and overall (cells with a valid sigma_F90)."""
    ok = compared[compared["f90_flag"] == "ok"]
    rows = [dict(g_bin=f"{g0:g}-{g1:g}", n_cells=len(grp), mean_diff_dex=grp["diff_dex"].mean(),
                 rms_diff_dex=float(np.sqrt(np.mean(grp["diff_dex"] ** 2))))
            for (g0, g1), grp in ok.groupby(["g_min", "g_max"], sort=True)]
    rows.append(dict(g_bin="all", n_cells=len(ok), mean_diff_dex=ok["diff_dex"].mean(),
                     rms_diff_dex=float(np.sqrt(np.mean(ok["diff_dex"] ** 2))) if len(ok) else np.nan))
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class FitResult:
    terms: pd.DataFrame
    fitted: dict
    coefficients: pd.DataFrame
    compared: pd.DataFrame
    rms: pd.DataFrame


def fit_all(f90: pd.DataFrame) -> FitResult:
    """The whole chain on a per-cell table (cells flagged other than 'ok' are not fitted)."""
    usable = f90[(f90["f90_flag"] == "ok") & np.isfinite(f90["sigma_f90_mas"])]
    terms = fit_direction_terms(usable)
    fitted = fit_polynomials(terms)
    compared = compare_cells(f90, fitted)
    return FitResult(terms, fitted, coefficient_table(fitted), compared, rms_table(compared))
