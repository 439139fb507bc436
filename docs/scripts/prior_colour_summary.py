"""The numbers of docs/prior_colour.md from two sweep runs: ``prior_model=colour`` and
``prior_model=colour_mean`` (default settings otherwise).

Prints, as Markdown tables:

1. the residual RMS of the colour cells about each form of the colour term (``colour_fit_forms.csv``);
2. per colour bin and G bin, the fraction inside the 90 % ellipse at the bin's fitted width
   (the prior a user gets) over the directions: median, min, max and how many cells lie in
   88-92 %, for both runs, and the same at the colour-blind fitted width;
3. the 90th-percentile position error at sigma_F90 (two visits) of the mean-centred prior
   against the zero-centred one of the same cells, and what the mean-centred prior does to
   sources with zero parallax and proper motion (quasars);
4. the runs' cell stage times (provenance).

and, given the real-sky run made with both as ``colour_priors``, its table per |b| band x
BP-RP tercile.

Run: ``python docs/scripts/prior_colour_summary.py COLOUR_RUN COLOUR_MEAN_RUN [REAL_SKY_RUN]``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

BAND = (0.88, 0.92)


def md(df: pd.DataFrame, floatfmt: str = "{:.3f}") -> str:
    cols = list(df.columns)
    out = ["| " + " | ".join(map(str, cols)) + " |", "|" + "---|" * len(cols)]
    for _, r in df.iterrows():
        out.append("| " + " | ".join(floatfmt.format(v) if isinstance(v, float) else str(v) for v in r) + " |")
    return "\n".join(out)


def forms(run: Path) -> pd.DataFrame:
    f = pd.read_csv(run / "colour_fit_forms.csv")
    return f.pivot_table(index="colour_bin", columns="form", values="rms_dex", sort=False).reset_index()


def fractions(run: Path, label: str) -> pd.DataFrame:
    c = pd.read_csv(run / "f90_colour_cells.csv")
    rows = []
    for (c0, c1, g0), grp in c.groupby(["bp_rp_min", "bp_rp_max", "g_min"], sort=True):
        fa, fb = grp["fraction_at_fitted"].dropna(), grp["fraction_at_colour_blind"].dropna()
        rows.append({"run": label, "BP-RP": f"{c0:g}..{c1:g}", "G": f"{g0:g}", "cells": len(grp),
                     "fitted: median": float(fa.median()) if len(fa) else np.nan,
                     "min": float(fa.min()) if len(fa) else np.nan, "max": float(fa.max()) if len(fa) else np.nan,
                     "in 88-92": f"{int(fa.between(*BAND).sum())}/{len(fa)}",
                     "colour-blind width: median": float(fb.median()) if len(fb) else np.nan,
                     "in 88-92 ": f"{int(fb.between(*BAND).sum())}/{len(fb)}"})
    return pd.DataFrame(rows)


def f90_rows(run: Path) -> pd.DataFrame:
    cells = pd.read_parquet(run / "cells.parquet")
    return cells[cells["at_f90"] & (cells["case"] == "two")].set_index("cell_id")


def blind_reference(colour: Path) -> str:
    """The colour-blind cells at the colour-blind fitted width (the paper's form): how many lie
    in 88-92 %, the yardstick for the colour cells."""
    from mcsweep.experiments.f90_sweep.colour_fit import fraction_at

    cells = pd.read_parquet(colour / "cells.parquet")
    f90 = pd.read_csv(colour / "f90_cells.csv")
    if "bp_rp_min" in f90:
        f90 = f90[f90["bp_rp_min"].isna()]
    f = pd.Series(fraction_at(cells, "two", f90["cell_id"], f90["fitted_sigma_f90_mas"])).dropna()
    return (f"colour-blind cells at the colour-blind fitted width (Eqs. 14-17): {int(f.between(*BAND).sum())}"
            f"/{len(f)} in 88-92 %, median {f.median():.3f}, 5-95 % range {f.quantile(0.05):.3f}-{f.quantile(0.95):.3f}")


def in_band(run: Path) -> str:
    c = pd.read_csv(run / "f90_colour_cells.csv")
    f = c["fraction_at_fitted"].dropna()
    return f"{int(f.between(*BAND).sum())}/{len(f)} colour cells in 88-92 % at their fitted width"


def mean_gain(colour: Path, colour_mean: Path) -> pd.DataFrame:
    z, m = f90_rows(colour), f90_rows(colour_mean)
    mean = m[["p_error_mas", "fraction_inside", "quasar_fraction_inside", "quasar_p_error_mas"]].rename(
        columns={"p_error_mas": "p_error_mas_mean", "fraction_inside": "fraction_inside_mean"})
    both = z[["g_min", "bp_rp_min", "p_error_mas", "fraction_inside"]].join(mean, how="inner")
    both["ratio"] = both["p_error_mas_mean"] / both["p_error_mas"]
    both["colour"] = both["bp_rp_min"].map(lambda v: "all" if pd.isna(v) else f"{v:g}..")
    g = both.groupby(["colour", "g_min"], sort=True)
    out = g.agg(cells=("ratio", "size"), error_ratio_median=("ratio", "median"), error_ratio_max=("ratio", "max"),
                frac_mean_median=("fraction_inside_mean", "median"),
                quasar_frac_median=("quasar_fraction_inside", "median"),
                quasar_frac_min=("quasar_fraction_inside", "min"),
                quasar_error_over_star_zero=("quasar_p_error_mas", "median"))
    # The quasars' 90th-percentile error against the stars' under the zero-centred prior.
    out["quasar_error_over_star_zero"] = (g["quasar_p_error_mas"].median() / g["p_error_mas"].median())
    return out.reset_index()


def real_sky(run: Path) -> pd.DataFrame:
    """``real_sky.csv`` of a run with the colour priors: per |b| band x BP-RP tercile (two visits,
    G = 6-8, Hipparcos truth) each prior's fraction inside and 90th-percentile error, intervals."""
    t = pd.read_csv(run / "real_sky.csv")
    t = t[(t["truth"] == "hipparcos") & (t["case"] == "two") & (t["g_bin"] == "6-8")]
    rows = []
    for (band, cbin), grp in t.groupby(["b_band_deg", "colour_bin"], sort=False):
        row = {"|b|": band, "BP-RP": cbin, "n": int(grp["n_valid"].iloc[0])}
        for _, r in grp.iterrows():
            row[f"{r['prior']} inside %"] = (f"{100 * r['fraction_inside']:.1f} "
                                             f"[{100 * r['fraction_lo']:.1f}-{100 * r['fraction_hi']:.1f}]")
            row[f"{r['prior']} p90 mas"] = f"{r['p_error_mas']:.2f} [{r['p_error_lo_mas']:.2f}-{r['p_error_hi_mas']:.2f}]"
        rows.append(row)
    return pd.DataFrame(rows)


def timings(run: Path) -> str:
    prov = json.loads((run / "provenance.json").read_text())
    t = prov.get("timings_s", {})
    return ", ".join(f"{k} {v:.0f} s" for k, v in t.items() if isinstance(v, (int, float)))


def main(colour: str, colour_mean: str, real_sky_run: str | None = None) -> None:
    colour, colour_mean = Path(colour), Path(colour_mean)
    if real_sky_run:
        print("## Real sky (Hipparcos truth, G = 6-8, two visits)\n")
        print(md(real_sky(Path(real_sky_run))) + "\n")
    print("## Forms of the colour term (RMS, dex)\n")
    print(md(forms(colour)) + "\n")
    print("## Fraction inside at the fitted width\n")
    print(md(pd.concat([fractions(colour, "colour"), fractions(colour_mean, "colour_mean")])) + "\n")
    print(f"colour: {in_band(colour)}; colour_mean: {in_band(colour_mean)}")
    print(blind_reference(colour) + "\n")
    print("## The mean: 90th-percentile error ratio (mean-centred / zero-centred) and quasars\n")
    print(md(mean_gain(colour, colour_mean)) + "\n")
    print(f"timings: colour: {timings(colour)}; colour_mean: {timings(colour_mean)}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
