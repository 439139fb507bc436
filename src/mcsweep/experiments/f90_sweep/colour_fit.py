"""The prior's colour term and its mean: what a sweep with ``prior_model=colour`` or
``colour_mean`` writes besides the colour-blind fit of :mod:`.fit`.

The form of the colour term is chosen on the evidence each run writes (``colour_fit_forms.csv``):
the residual RMS in dex of the colour cells' log10 sigma_F90 about

* ``colour_blind``: the colour-blind surface (Eqs. 14-17 fitted to the colour-blind cells);
* ``offset``: that surface plus one constant per colour bin (log10 sigma_F90 shifted);
* ``offset_linear_g``: plus a constant and a slope in G per colour bin;
* ``per_bin``: Eqs. 14-17 fitted separately to each colour bin's cells (Sect. 3.4's two
  least-squares steps, the same polynomial degrees);
* ``per_bin_g``: only the first of those steps, Eq. 14 per colour bin and G bin, with s0, s1,
  s2 interpolated linearly in G between the bins' centres (``colour_terms.csv``).

The prior a run gives is the ``per_bin_g`` form. Both per-bin forms let the direction terms
s1, s2 differ between colours (giants and dwarfs are spread differently along a sight line,
so their sigma_F90 changes differently with |b|), but within a colour bin the mix of giants
and dwarfs changes with G faster than the polynomials of Eqs. 15-17 can follow: on the
default sweep (docs/prior_colour.md) ``per_bin`` leaves 0.20 and 0.42 dex RMS in the bins
redder than BP-RP = 1.23 and ``per_bin_g`` 0.14 and 0.30 dex, with 3 parameters for each of
a bin's 48-direction G bins. ``colour_coefficients.csv`` (Eqs. 15-17 per bin) is still
written, to compare with the paper's form. The forms' RMS are there to judge the choice on
each run.

``prior_means.csv`` lists each cell's mean parallax and proper motion, the prior's centre
with ``prior_model.mean``; :class:`mcsweep.prior.Prior` interpolates it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...prior.colour import bin_label
from ...prior.formula import sigma_from_nodes
from ...prior.run_record import COLOUR_COEFFICIENTS_FILE, COLOUR_TERMS_FILE, POLY_DEGREES
from .pencil_beam import COLOUR_MIN_STARS
from .fit import coefficient_table, compare_cells, evaluate_formula, fit_all

__all__ = ["COLOUR_FILES", "colour_cells", "colour_tables", "fraction_at", "fit_forms", "means_table"]

#: The colour term's tables in a run directory (with ``prior_model.colour_edges``).
COLOUR_FILES = (COLOUR_TERMS_FILE, COLOUR_COEFFICIENTS_FILE, "f90_colour_cells.csv", "colour_fit_forms.csv")
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
    """The colour term's files (:data:`COLOUR_FILES`): ``colour_terms.csv`` (Eq. 14 per colour
    bin and G bin, with bootstrap intervals: the prior's form, module notes),
    ``colour_coefficients.csv`` (Eqs. 15-17 per colour bin), ``f90_colour_cells.csv`` (every
    colour cell with the prior's sigma_F90 at it, the Eqs. 15-17 one and the colour-blind one;
    with ``curves``, the sweep's ``cells.parquet``, also the fraction inside at the prior's
    and at the colour-blind width in the ``f90_case``) and ``colour_fit_forms.csv``."""
    cells = colour_cells(f90)
    terms, coefs, compared = [], [], []
    for (c0, c1), grp in cells.groupby(["bp_rp_min", "bp_rp_max"], sort=True):
        t, c, comp = _bin_fit(grp)
        terms.append(t.assign(bp_rp_min=c0, bp_rp_max=c1))
        coefs.append(c.assign(bp_rp_min=c0, bp_rp_max=c1))
        compared.append(comp.assign(fitted_sigma_f90_mas=_node_sigma(t, comp)))
    comp = pd.concat(compared, ignore_index=True) if compared else cells.copy()
    if len(comp):
        comp["colour_blind_sigma_f90_mas"] = evaluate_formula(
            blind_fitted, comp["l_deg"].to_numpy(float), comp["b_deg"].to_numpy(float),
            ((comp["g_min"] + comp["g_max"]) / 2).to_numpy(float))
        if curves is not None:
            for width in ("fitted", "colour_blind"):
                comp[f"fraction_at_{width}"] = fraction_at(curves, f90_case, comp["cell_id"],
                                                           comp[f"{width}_sigma_f90_mas"])
    return {COLOUR_TERMS_FILE: _ordered(terms, ["bp_rp_min", "bp_rp_max"]),
            COLOUR_COEFFICIENTS_FILE: _ordered(coefs, ["bp_rp_min", "bp_rp_max"]),
            "f90_colour_cells.csv": comp, "colour_fit_forms.csv": fit_forms(comp, blind_fitted)}


def _ordered(parts: list[pd.DataFrame], first: list[str]) -> pd.DataFrame:
    if not parts:
        return pd.DataFrame(columns=first)
    t = pd.concat(parts, ignore_index=True)
    return t[first + [c for c in t.columns if c not in first]]


def _bin_fit(grp: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """One colour bin: its Eq. 14 terms per G bin, its Eqs. 15-17 coefficients (with the G range
    of the cells that determine them) and its cells with the Eqs. 15-17 sigma_F90."""
    ok = _usable(grp)
    if len(ok):
        fit = fit_all(grp)
        terms, table, comp = fit.terms, fit.coefficients, fit.compared
    else:  # no cell of this colour has a sigma_F90 (e.g. too few stars at every G)
        undetermined = {name: np.full(deg + 1, np.nan) for name, deg in POLY_DEGREES.items()}
        terms = pd.DataFrame(columns=["g_min", "g_max", "g", "s0", "s1", "s2", "n_cells", "rms_dex"])
        table = coefficient_table(undetermined).assign(fitted_lo=np.nan, fitted_hi=np.nan)
        comp = compare_cells(grp, undetermined)
    table = table.drop(columns=["paper", "difference", "paper_inside"], errors="ignore").assign(
        n_cells=int(len(ok)), g_fit_min=float(ok["g_min"].min()) if len(ok) else np.nan,
        g_fit_max=float(ok["g_max"].max()) if len(ok) else np.nan)
    comp = comp.rename(columns={"fitted_sigma_f90_mas": "eqs15_17_sigma_f90_mas"})
    return terms, table, comp


def _node_sigma(terms: pd.DataFrame, cells: pd.DataFrame) -> np.ndarray:
    """sigma_F90 of the prior's form (Eq. 14 per G bin, linear in G between the bins' centres)
    at each cell; NaN for a bin without any determined G bin."""
    nodes = terms.dropna(subset=["s0", "s1", "s2"]).sort_values("g")
    if nodes.empty:
        return np.full(len(cells), np.nan)
    g = ((cells["g_min"] + cells["g_max"]) / 2).to_numpy(float)
    return sigma_from_nodes(cells["l_deg"].to_numpy(float), cells["b_deg"].to_numpy(float), g,
                            nodes["g"].to_numpy(float), nodes[["s0", "s1", "s2"]].to_numpy(float))


def fraction_at(curves: pd.DataFrame, case: str, cell_ids, sigma_mas) -> np.ndarray:
    """Fraction inside the P ellipse of each cell's ``case`` at a prior ``sigma_mas``, read off
    the cell's curve over the prior grid (linear in log sigma, as sigma_F90 is found,
    Sect. 3.3); NaN outside the grid or where the width is undetermined. Every cell of a
    sweep has the same grid (``prior_grid``), so the curves are one cells x grid table."""
    grid = curves[(curves["case"] == case) & ~curves["at_f90"].astype(bool)]
    table = grid.pivot(index="cell_id", columns="sigma_prior_mas", values="fraction_inside")
    x = np.log10(table.columns.to_numpy(float))
    f = table.reindex(pd.Index(cell_ids)).to_numpy(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.log10(np.asarray(sigma_mas, float))
    ok = np.isfinite(q) & (q >= x[0]) & (q <= x[-1])
    j = np.clip(np.searchsorted(x, np.where(ok, q, x[0]), side="right") - 1, 0, len(x) - 2)
    rows = np.arange(len(f))
    # np.interp's own arithmetic (slope from the left node), row by row at once.
    slope = (f[rows, j + 1] - f[rows, j]) / (x[j + 1] - x[j])
    at = np.where(q == x[j + 1], f[rows, j + 1], slope * (q - x[j]) + f[rows, j])
    return np.where(ok, at, np.nan)


def fit_forms(compared: pd.DataFrame, blind_fitted: dict) -> pd.DataFrame:
    """Residual RMS [dex] of the usable colour cells about each candidate form of the colour
    term (module notes), per colour bin and over all, with the number of parameters."""
    ok = _usable(compared)
    if ok.empty:
        return pd.DataFrame(columns=["form", "colour_bin", "n_cells", "n_parameters", "rms_dex"])
    y = np.log10(ok["sigma_f90_mas"].to_numpy(float))
    g = ((ok["g_min"] + ok["g_max"]) / 2).to_numpy(float)
    blind = np.log10(evaluate_formula(blind_fitted, ok["l_deg"].to_numpy(float), ok["b_deg"].to_numpy(float), g))
    own = np.log10(ok["eqs15_17_sigma_f90_mas"].to_numpy(float))
    nodes = np.log10(ok["fitted_sigma_f90_mas"].to_numpy(float))
    labels = [bin_label(a, b) for a, b in zip(ok["bp_rp_min"], ok["bp_rp_max"])]
    bins = sorted(set(labels), key=lambda s: float(s.split("..")[0]))
    lab = np.array(labels)
    resid = {"colour_blind": y - blind, "offset": np.empty_like(y), "offset_linear_g": np.empty_like(y),
             "per_bin": y - own, "per_bin_g": y - nodes}
    for b in bins:
        m = lab == b
        r = y[m] - blind[m]
        resid["offset"][m] = r - r.mean()
        a = np.column_stack([np.ones(m.sum()), g[m]])
        resid["offset_linear_g"][m] = r - a @ np.linalg.lstsq(a, r, rcond=None)[0]
    n_g = ok.groupby(["bp_rp_min", "g_min"]).ngroups
    n_par = {"colour_blind": 0, "offset": len(bins), "offset_linear_g": 2 * len(bins), "per_bin": 9 * len(bins),
             "per_bin_g": 3 * n_g}
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
    # A colour cell whose width is not determined (too few stars, COLOUR_MIN_STARS) gets no
    # centre either: its stars take the colour-blind cell's, not a mean of a handful of stars.
    few = out["bp_rp_min"].notna() & (out["n_mean_stars"] < COLOUR_MIN_STARS)
    out.loc[few, _MEANS] = np.nan
    return out[cols].reset_index(drop=True)
