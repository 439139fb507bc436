"""The prior's colour term and its mean: what a sweep with ``prior_model=colour`` or
``colour_mean`` writes besides the colour-blind fit of :mod:`.fit`.

The form of the colour term is chosen on the evidence each run writes (``colour_fit_forms.csv``):
the residual RMS in dex of the colour cells' log10 sigma_F90 about

* ``colour_blind``: the colour-blind surface (Eqs. 14-17 fitted to the colour-blind cells);
* ``offset``: that surface plus one constant per colour bin (log10 sigma_F90 shifted);
* ``offset_linear_g``: plus a constant and a slope in G per colour bin;
* ``per_bin``: Eqs. 14-17 fitted separately to each colour bin's cells (Sect. 3.4's two
  least-squares steps, the same polynomial degrees).

The prior a run gives is the ``per_bin`` form (``colour_coefficients.csv``), the only one of
the four that lets the direction terms s1, s2 differ between colours: giants and dwarfs
are spread differently along a sight line, so their sigma_F90 changes differently with |b|.
The forms' RMS are there to judge that choice on each run (docs/prior_colour.md).

``prior_means.csv`` lists each cell's mean parallax and proper motion, the prior's centre
with ``prior_model.mean``; :class:`mcsweep.prior.Prior` interpolates it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .fit import POLY_DEGREES, coefficient_table, compare_cells, evaluate_formula, fit_all

__all__ = ["COLOUR_FILES", "MEANS_FILE", "colour_cells", "colour_tables", "fraction_at", "fit_forms", "means_table"]

#: The colour term's tables in a run directory (with ``prior_model.colour_edges``).
COLOUR_FILES = ("colour_coefficients.csv", "f90_colour_cells.csv", "colour_fit_forms.csv")
#: The prior's centre per cell (with ``prior_model.mean``).
MEANS_FILE = "prior_means.csv"
_MEANS = ["mean_parallax_mas", "mean_pml_masyr", "mean_pmb_masyr"]


def colour_cells(f90: pd.DataFrame) -> pd.DataFrame:
    """The cells with a colour bin."""
    if "bp_rp_min" not in f90:
        return f90.iloc[:0]
    return f90[f90["bp_rp_min"].notna()].reset_index(drop=True)


def _usable(cells: pd.DataFrame) -> pd.DataFrame:
    return cells[(cells["f90_flag"] == "ok") & np.isfinite(cells["sigma_f90_mas"])]


def colour_tables(f90: pd.DataFrame, blind_fitted: dict, curves: pd.DataFrame | None = None,
                  f90_case: str | None = None) -> dict[str, pd.DataFrame]:
    """``colour_coefficients.csv`` (Eqs. 15-17 per colour bin, with bootstrap intervals),
    ``f90_colour_cells.csv`` (every colour cell with its bin's fitted sigma_F90 and the
    colour-blind one; with ``curves``, the sweep's ``cells.parquet``, also the fraction inside
    at each of the two in the ``f90_case``) and ``colour_fit_forms.csv`` (module notes)."""
    cells = colour_cells(f90)
    coefs, compared = [], []
    for (c0, c1), grp in cells.groupby(["bp_rp_min", "bp_rp_max"], sort=True):
        if len(_usable(grp)):
            fit = fit_all(grp)
            table, comp = fit.coefficients, fit.compared
        else:  # no cell of this colour has a sigma_F90 (e.g. too few stars at every G)
            undetermined = {name: np.full(deg + 1, np.nan) for name, deg in POLY_DEGREES.items()}
            table = coefficient_table(undetermined).assign(fitted_lo=np.nan, fitted_hi=np.nan)
            comp = compare_cells(grp, undetermined)
        ok = _usable(grp)
        # The G range of the cells that determine the bin's fit: the prior of a colour is
        # evaluated within it only (the paper's rule at its faint end, Sect. 3.4: the value at
        # the edge beyond it), since a colour's polynomials are unconstrained where its cells
        # had too few stars (COLOUR_MIN_STARS).
        coefs.append(table.drop(columns=["paper", "difference", "paper_inside"], errors="ignore")
                     .assign(bp_rp_min=c0, bp_rp_max=c1, n_cells=int(len(ok)),
                             g_fit_min=float(ok["g_min"].min()) if len(ok) else np.nan,
                             g_fit_max=float(ok["g_max"].max()) if len(ok) else np.nan))
        compared.append(comp)
    coef = pd.concat(coefs, ignore_index=True) if coefs else pd.DataFrame()
    if len(coef):
        coef = coef[["bp_rp_min", "bp_rp_max", "term", "fitted", "fitted_lo", "fitted_hi", "n_cells", "g_fit_min",
                     "g_fit_max"]]
    comp = pd.concat(compared, ignore_index=True) if compared else cells.copy()
    if len(comp):
        comp["colour_blind_sigma_f90_mas"] = evaluate_formula(
            blind_fitted, comp["l_deg"].to_numpy(float), comp["b_deg"].to_numpy(float),
            ((comp["g_min"] + comp["g_max"]) / 2).to_numpy(float))
        if curves is not None:
            for width in ("fitted", "colour_blind"):
                comp[f"fraction_at_{width}"] = fraction_at(curves, f90_case, comp["cell_id"],
                                                           comp[f"{width}_sigma_f90_mas"])
    return {"colour_coefficients.csv": coef, "f90_colour_cells.csv": comp,
            "colour_fit_forms.csv": fit_forms(comp, blind_fitted)}


def fraction_at(curves: pd.DataFrame, case: str, cell_ids, sigma_mas) -> np.ndarray:
    """Fraction inside the P ellipse of each cell's ``case`` at a prior ``sigma_mas``, read off
    the cell's curve over the prior grid (linear in log sigma, as sigma_F90 is found,
    Sect. 3.3); NaN outside the grid or where the width is undetermined."""
    grid = curves[(curves["case"] == case) & ~curves["at_f90"].astype(bool)]
    by_cell = {cid: g.sort_values("sigma_prior_mas") for cid, g in grid.groupby("cell_id", sort=False)}
    out = np.full(len(cell_ids), np.nan)
    for i, (cid, sig) in enumerate(zip(cell_ids, np.asarray(sigma_mas, float))):
        g = by_cell.get(cid)
        if g is None or not np.isfinite(sig) or sig <= 0:
            continue
        x, y = np.log10(g["sigma_prior_mas"].to_numpy(float)), g["fraction_inside"].to_numpy(float)
        if x[0] <= np.log10(sig) <= x[-1]:
            out[i] = np.interp(np.log10(sig), x, y)
    return out


def fit_forms(compared: pd.DataFrame, blind_fitted: dict) -> pd.DataFrame:
    """Residual RMS [dex] of the usable colour cells about each candidate form of the colour
    term (module notes), per colour bin and over all, with the number of parameters."""
    ok = _usable(compared)
    if ok.empty:
        return pd.DataFrame(columns=["form", "colour_bin", "n_cells", "n_parameters", "rms_dex"])
    y = np.log10(ok["sigma_f90_mas"].to_numpy(float))
    g = ((ok["g_min"] + ok["g_max"]) / 2).to_numpy(float)
    blind = np.log10(evaluate_formula(blind_fitted, ok["l_deg"].to_numpy(float), ok["b_deg"].to_numpy(float), g))
    own = np.log10(ok["fitted_sigma_f90_mas"].to_numpy(float))
    labels = [f"{a:g}..{b:g}" for a, b in zip(ok["bp_rp_min"], ok["bp_rp_max"])]
    bins = sorted(set(labels), key=lambda s: float(s.split("..")[0]))
    lab = np.array(labels)
    resid = {"colour_blind": y - blind, "offset": np.empty_like(y), "offset_linear_g": np.empty_like(y),
             "per_bin": y - own}
    for b in bins:
        m = lab == b
        r = y[m] - blind[m]
        resid["offset"][m] = r - r.mean()
        a = np.column_stack([np.ones(m.sum()), g[m]])
        resid["offset_linear_g"][m] = r - a @ np.linalg.lstsq(a, r, rcond=None)[0]
    n_par = {"colour_blind": 0, "offset": len(bins), "offset_linear_g": 2 * len(bins), "per_bin": 9 * len(bins)}
    rows = []
    for form, r in resid.items():
        for b in bins + ["all"]:
            # Cells of a bin without its own fit (too few G bins) have no per_bin residual.
            m = (np.ones(len(r), bool) if b == "all" else lab == b) & np.isfinite(r)
            rows.append(dict(form=form, colour_bin=b, n_cells=int(m.sum()), n_parameters=n_par[form],
                             rms_dex=float(np.sqrt(np.mean(r[m] ** 2))) if m.any() else np.nan))
    return pd.DataFrame(rows)


def means_table(f90: pd.DataFrame) -> pd.DataFrame:
    """``prior_means.csv``: each cell's direction, G bin, colour bin (NaN: colour-blind) and the
    mean parallax and galactic proper motion of its stars, with the number of stars averaged."""
    cols = ["l_deg", "b_deg", "g_min", "g_max", "bp_rp_min", "bp_rp_max", *_MEANS, "n_mean_stars"]
    out = f90.copy()
    for c in ("bp_rp_min", "bp_rp_max"):
        if c not in out:
            out[c] = np.nan
    return out[cols].reset_index(drop=True)
