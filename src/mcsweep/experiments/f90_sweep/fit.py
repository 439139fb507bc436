"""Fit of the paper's all-sky approximation to a sweep's simulated sigma_F90 values.

Two least-squares steps, as in Sect. 3.4: per G bin over the directions,
``log10 sigma_F90 = s0 + s1 |sin b| + s2 cos b cos l`` (Eq. 14); then the coefficients
against G with the polynomial degrees of Eqs. 15-17 (2, 3 and 1). G of a bin is its
centre. The comparison with the paper evaluates Eqs. 14-17 at each cell's (l, b, G).

Uncertainties: the whole chain is repeated on bootstrap resamples of the cells (within
each G bin, directions drawn with replacement), which carries both the Monte Carlo noise
of each cell's sigma_F90 and the scatter of the cells about Eq. 14. Intervals are the
16th-84th percentiles of the resampled coefficients (FIT_INTERVAL).

The sweep computes this fit when it aggregates its cells (``mcsweep.experiments.f90_sweep.runner.run_sweep``)
and writes :data:`FIT_FILES` and ``prior_maps.fits`` (``prior_maps_for_run``); the
report only reads them back (:func:`read_fit`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import UserInputError
from ...prior import PAPER_COEFFICIENTS, Prior, sigma_from_coefficients
from ...prior.maps import prior_maps_bytes
from ...prior.run_record import POLY_DEGREES
from . import FIT_FILES
from .pencil_beam import COLOUR_COLUMNS, CELL_MEAN_COLUMNS

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
    "bootstrap_fit",
    "FIT_BOOTSTRAP",
    "FIT_INTERVAL",
    "MAP_CELL_COLUMNS",
    "f90_table",
    "colour_blind",
    "fit_tables",
    "read_fit",
    "prior_maps_for_run",
]

#: Bootstrap resamples of the cells for the fit's uncertainties, and their fixed seed
#: (the same cells always give the same intervals, so a resumed sweep rewrites them unchanged).
FIT_BOOTSTRAP = 400
FIT_BOOTSTRAP_SEED = 14
#: Percentiles of the bootstrap distribution reported as the interval (68 %).
FIT_INTERVAL = (16.0, 84.0)
#: Per-cell columns copied into the CELLS extension of ``prior_maps.fits``.
MAP_CELL_COLUMNS = ("cell_id", "l_deg", "b_deg", "g_min", "g_max", "g", "n_stars", "radius_deg", "f90_flag",
                    "sigma_f90_mas", "fitted_sigma_f90_mas", "paper_sigma_f90_mas")


def f90_table(cells: pd.DataFrame) -> pd.DataFrame:
    """One row per cell from the sweep's ``cells.parquet`` (one row per cell, case and
    prior): the cell, its sigma_F90 and flag, and the fraction inside the P ellipse at
    sigma_F90 of every case (columns ``fraction_at_f90_<case>``)."""
    base = cells.drop_duplicates("cell_id")[["cell_id", "l_deg", "b_deg", "ra_deg", "dec_deg", "g_min",
                                             "g_max", "n_stars", "n_in_cone", "radius_deg", "n_groups",
                                             "sigma_f90_mas", "f90_flag"]
                                            + [c for c in ("sigma_f90_lo_mas", "sigma_f90_hi_mas",
                                                           "ill_determined", *COLOUR_COLUMNS, *CELL_MEAN_COLUMNS)
                                               if c in cells]]
    at = cells[cells["at_f90"]].pivot_table(index="cell_id", columns="case", values="fraction_inside")
    at.columns = [f"fraction_at_f90_{c}" for c in at.columns]
    return base.merge(at, left_on="cell_id", right_index=True, how="left").reset_index(drop=True)


def colour_blind(f90: pd.DataFrame) -> pd.DataFrame:
    """The cells without a colour bin (every cell of a sweep without the colour axis)."""
    if "bp_rp_min" not in f90:
        return f90
    return f90[f90["bp_rp_min"].isna()].reset_index(drop=True)


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


def coefficient_table(fitted: dict[str, np.ndarray], boot: dict[str, np.ndarray] | None = None) -> pd.DataFrame:
    """Fitted and paper coefficients; with ``boot`` (name -> (n_resamples, degree + 1))
    also ``fitted_lo``, ``fitted_hi`` (FIT_INTERVAL) and whether the paper's value lies inside."""
    rows = []
    for name in ("s0", "s1", "s2"):
        for power, paper in enumerate(PAPER_COEFFICIENTS[name]):
            ours = float(fitted[name][power])
            row = dict(term=f"{name}_c{power}", fitted=ours, paper=paper, difference=ours - paper)
            if boot is not None:
                lo, hi = _interval(boot[name][:, power])
                row.update(fitted_lo=lo, fitted_hi=hi, paper_inside=bool(lo <= paper <= hi))
            rows.append(row)
    return pd.DataFrame(rows)


def _interval(values) -> tuple[float, float]:
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan"), float("nan")
    lo, hi = np.percentile(v, FIT_INTERVAL)
    return float(lo), float(hi)


def bootstrap_fit(usable: pd.DataFrame, n_resamples: int = FIT_BOOTSTRAP, seed: int = FIT_BOOTSTRAP_SEED):
    """Eq. 14 terms and Eqs. 15-17 coefficients on resamples of the cells (module notes).

    Returns ``(terms, coefficients)``: terms (n_resamples, n_bins, 3) for s0, s1, s2 per
    G bin, and name -> (n_resamples, degree + 1).
    """
    rng = np.random.default_rng(seed)
    bins = []
    for (g0, g1), grp in usable.groupby(["g_min", "g_max"], sort=True):
        bins.append(((g0 + g1) / 2, direction_design(grp["l_deg"].to_numpy(float), grp["b_deg"].to_numpy(float)),
                     np.log10(grp["sigma_f90_mas"].to_numpy(float))))
    terms = np.full((n_resamples, len(bins), 3), np.nan)
    coefs = {name: np.full((n_resamples, deg + 1), np.nan) for name, deg in POLY_DEGREES.items()}
    g = np.array([b[0] for b in bins])
    for k in range(n_resamples):
        for i, (_, a, y) in enumerate(bins):
            idx = rng.integers(0, len(y), len(y))
            # Same rule as fit_direction_terms: no fit below 3 cells or rank 3.
            if len(y) >= 3 and np.linalg.matrix_rank(a[idx]) == 3:
                terms[k, i] = np.linalg.lstsq(a[idx], y[idx], rcond=None)[0]
        ok = np.isfinite(terms[k]).all(axis=1)
        for j, (name, deg) in enumerate(POLY_DEGREES.items()):
            if ok.sum() > deg:
                coefs[name][k] = np.polynomial.polynomial.polyfit(g[ok], terms[k, ok, j], deg)
    return terms, coefs


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
    """The whole chain on a per-cell table (cells flagged other than 'ok' are not fitted).
    ``f90`` holds the colour-blind cells (:func:`colour_blind`)."""
    usable = f90[(f90["f90_flag"] == "ok") & np.isfinite(f90["sigma_f90_mas"])]
    terms = fit_direction_terms(usable)
    fitted = fit_polynomials(terms)
    boot_terms, boot_coefs = bootstrap_fit(usable)
    for j, name in enumerate(("s0", "s1", "s2")):
        iv = np.array([_interval(boot_terms[:, i, j]) for i in range(len(terms))]).reshape(-1, 2)
        terms[f"{name}_lo"], terms[f"{name}_hi"] = iv[:, 0], iv[:, 1]
    compared = compare_cells(f90, fitted)
    return FitResult(terms, fitted, coefficient_table(fitted, boot_coefs), compared, rms_table(compared))


def fit_tables(fit: FitResult) -> dict[str, pd.DataFrame]:
    """The tables a sweep writes (as CSV) for ``fit``, by file name (:data:`FIT_FILES`)."""
    return {name: getattr(fit, field) for name, field in FIT_FILES.items()}


def read_fit(run_dir) -> FitResult:
    """The fit a sweep wrote into ``run_dir`` (:data:`FIT_FILES`), read back without refitting.

    Parameters
    ----------
    run_dir : str or path-like
        A sweep's run directory.

    Returns
    -------
    FitResult
        Its tables; ``fitted`` (Eqs. 15-17, increasing power of G) is the ``fitted``
        column of ``coefficients.csv``, rows ``s0_c0`` ... ``s2_c1``, NaN where it was
        not determined.

    Examples
    --------
    These read a run's files; the lines are skipped when the examples run as
    tests (no run directory there).

    >>> from mcsweep.experiments.f90_sweep.fit import read_fit
    >>> fit = read_fit('results/default')  # doctest: +SKIP
    >>> # Eqs. 15-17: ours and the paper's coefficients
    >>> fit.coefficients[['term', 'fitted', 'paper']]  # doctest: +SKIP
    """
    run_dir = Path(run_dir)
    tables = {field: pd.read_csv(run_dir / name) for name, field in FIT_FILES.items()}
    by_term = dict(zip(tables["coefficients"]["term"].astype(str), tables["coefficients"]["fitted"].astype(float)))
    fitted = {name: np.array([by_term.get(f"{name}_c{k}", np.nan) for k in range(deg + 1)], float)
              for name, deg in POLY_DEGREES.items()}
    return FitResult(tables["terms"], fitted, tables["coefficients"], tables["compared"], tables["rms"])


def prior_maps_for_run(run_dir, fit: FitResult, *, nside: int) -> bytes:
    """Content of ``prior_maps.fits`` for a sweep (:mod:`mcsweep.prior.maps`): the run's prior
    at every G bin centre, and the cells (:data:`MAP_CELL_COLUMNS`).

    The prior is read back with :meth:`Prior.from_run` from the ``coefficients.csv`` the
    sweep has just written, so the maps hold exactly what a user of the run directory gets;
    NaN maps (``FITTED = F``) when the polynomials could not be fitted.
    """
    g_centres = sorted(set(fit.compared["g"].astype(float)))
    try:
        run_prior = Prior.from_run(run_dir)
    except UserInputError:
        run_prior = None
    cells = fit.compared[[c for c in MAP_CELL_COLUMNS if c in fit.compared.columns]]
    return prior_maps_bytes(run_prior, g_centres, nside=nside, cells=cells)
