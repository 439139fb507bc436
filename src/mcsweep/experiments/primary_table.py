"""Table 3 of the paper (one-year global solution): the published values and ours.

Michalik et al. (2015), Table 3 ("Global astrometric solutions using 12 months of
simulated Gaia data. The attitude is determined as part of the solution"): per subset
(<= 4, > 4 FoV transits), prior and class (G ~ 11, 15, 19), the fraction of actual
position errors inside the 90 % confidence ellipse and the 90th percentile of the
actual position errors [mas]. Columns as Table 2
(:mod:`mcsweep.experiments.secondary_table`); here the transits are all those of one
year minus the dead time (no dilution).

Every fraction carries its binomial 1-sigma interval ``sqrt(f (1 - f) / n)`` (n the
stars with a confidence region in the cell). The paper gives no uncertainties; at its
5e5 stars per class the binomial sigma of a 90 % fraction is 0.04 % or more (fewer stars
per subset).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from .secondary_table import PAPER_CONFIDENCE, PAPER_G_CLASSES, SUBSETS, error_percentile, g_label, subset_masks

__all__ = ["PAPER_TABLE3", "PAPER_G_CLASSES", "TABLE3_COLUMNS", "paper_value3", "binomial_sigma",
           "table3_rows", "table3_markdown", "prior_label"]

#: Table 3 transcribed from the LaTeX source: (subset, prior) -> (fractions in per cent
#: for G ~ 11, 15, 19; 90th percentiles of the position errors in mas).
PAPER_TABLE3: Mapping[tuple[str, str], tuple[tuple[float, ...], tuple[float, ...]]] = MappingProxyType({
    ("<=4", "F90"): ((76.5, 86.8, 92.4), (1.2, 0.7, 2.0)),
    ("<=4", "10F90"): ((89.1, 90.4, 94.3), (1.4, 1.1, 4.2)),
    ("<=4", "1000mas"): ((89.7, 89.8, 90.6), (3.8, 3.4, 17.7)),
    (">4", "F90"): ((32.3, 53.3, 88.0), (0.2, 0.2, 0.8)),
    (">4", "10F90"): ((88.6, 89.3, 90.4), (0.1, 0.2, 1.0)),
    (">4", "1000mas"): ((88.7, 89.4, 90.0), (0.1, 0.2, 1.1)),
})
TABLE3_COLUMNS = ("subset", "prior", "g_class", "n_stars", "n_valid", "n_inside", "fraction_inside",
                  "fraction_sigma", "p90_error_mas", "paper_fraction_inside", "paper_p90_error_mas",
                  "error_percentile")


def prior_label(prior: str) -> str:
    """The paper's row label of a prior setting ('10F90' -> '10 sigma_F90')."""
    if prior.endswith("F90"):
        k = prior[:-3]
        return "sigma_F90" if k in ("", "1") else f"{k} sigma_F90"
    return prior.replace("mas", " mas")


def paper_value3(subset: str, prior: str, g_class: float, confidence: float) -> tuple[float, float]:
    """(fraction, 90th percentile [mas]) of the paper's Table 3, NaN where not comparable."""
    try:
        i = PAPER_G_CLASSES.index(float(g_class))
    except ValueError:
        return float("nan"), float("nan")
    key = (subset, "F90" if prior == "1F90" else prior)
    if key not in PAPER_TABLE3 or abs(confidence - PAPER_CONFIDENCE) >= 1e-12:
        return float("nan"), float("nan")
    frac, p90 = PAPER_TABLE3[key]
    return frac[i] / 100.0, p90[i]


def binomial_sigma(f: float, n: int) -> float:
    """1-sigma binomial uncertainty of a fraction ``f`` of ``n`` stars."""
    return float(np.sqrt(f * (1.0 - f) / n)) if n > 0 and np.isfinite(f) else float("nan")


def table3_rows(results: Mapping[str, pd.DataFrame], g_classes: Sequence[float], confidence: float) -> pd.DataFrame:
    """``table3.csv``: one row per subset x prior x class (the primary sources are not tabulated).

    ``results[prior]`` holds the per-star results of one solution (columns ``class_key``,
    ``n_fov``, ``inside``, ``err_mas``; :func:`mcsweep.experiments.primary.solve_prior`).
    """
    q = error_percentile(confidence)
    rows = []
    for subset in SUBSETS:
        for prior, res in results.items():
            masks = subset_masks(res["n_fov"].to_numpy())
            for g in g_classes:
                sel = masks[subset] & (res["class_key"].to_numpy() == int(round(100 * g)))
                inside = res["inside"].to_numpy()[sel]
                err = res["err_mas"].to_numpy()[sel].astype(float)
                ok = inside >= 0
                n_valid, n_in = int(ok.sum()), int((inside == 1).sum())
                frac = n_in / n_valid if n_valid else float("nan")
                p90 = float(np.percentile(err[ok], q)) if n_valid else float("nan")
                pf, pp = paper_value3(subset, prior, g, confidence)
                rows.append((subset, prior, g_label(g), int(sel.sum()), n_valid, n_in, frac,
                             binomial_sigma(frac, n_valid), p90, pf, pp, q))
    return pd.DataFrame(rows, columns=list(TABLE3_COLUMNS))


def _cell_fraction(f, s, paper) -> str:
    o = "–" if not np.isfinite(f) else f"{100 * f:.1f} ± {100 * s:.1f}"
    return o if not np.isfinite(paper) else f"{o} ({100 * paper:.1f})"


def _cell_error(e, paper) -> str:
    o = "–" if not np.isfinite(e) else f"{e:.3g}"
    return o if not np.isfinite(paper) else f"{o} ({paper:.3g})"


def table3_layout(table: pd.DataFrame, confidence: float) -> dict[str, pd.DataFrame]:
    """Per subset: priors x (fraction ± 1 sigma | percentile) per class, ``ours (paper)``."""
    classes = list(dict.fromkeys(table["g_class"]))
    pct = f"{100 * confidence:g}"
    out = {}
    for subset in SUBSETS:
        part = table[table["subset"] == subset]
        rows = []
        for prior in dict.fromkeys(part["prior"]):
            r = part[part["prior"] == prior].set_index("g_class")
            row = {"prior sigma_plx,p": prior_label(prior)}
            for g in classes:
                row[f"in {pct} % ellipse, G~{g} [%]"] = _cell_fraction(
                    r.at[g, "fraction_inside"], r.at[g, "fraction_sigma"], r.at[g, "paper_fraction_inside"])
            for g in classes:
                row[f"p{pct} error, G~{g} [mas]"] = _cell_error(r.at[g, "p90_error_mas"],
                                                                r.at[g, "paper_p90_error_mas"])
            rows.append(row)
        out[subset] = pd.DataFrame(rows)
    return out


def table3_markdown(table: pd.DataFrame, confidence: float, notes: Sequence[str] = ()) -> str:
    """``table3.md``: our Table 3 next to the paper's (in parentheses)."""
    lines = ["# Table 3: one-year global solution, attitude from the same data (ours ± binomial 1 sigma, "
             "paper in parentheses)", ""]
    lines += list(notes) + ([""] if notes else [])
    for subset, df in table3_layout(table, confidence).items():
        part = table[(table["subset"] == subset)].drop_duplicates("g_class")
        n = ", ".join(f"G~{g}: {int(v)}" for g, v in zip(part["g_class"], part["n_stars"]))
        lines += [f"## Subset of stars with {'<= 4' if subset == '<=4' else '> 4'} field-of-view transits "
                  f"({n} stars)", ""]
        cols = list(map(str, df.columns))
        lines += ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
        lines += ["| " + " | ".join(map(str, row)) + " |" for row in df.itertuples(index=False)] + [""]
    return "\n".join(lines)
