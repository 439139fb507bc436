"""Would a form without Eq. 14's shape describe the colour cells better? Leave one direction out.

For every colour bin and G bin of a ``prior_model=colour`` sweep, each direction's log10
sigma_F90 is predicted from the other directions' cells in two ways:

* ``eq14``: Eq. 14 (s0 + s1 |sin b| + s2 cos b cos l) fitted to the other cells, the prior's
  form (per colour bin and G bin);
* ``neighbours``: the mean of the 4 nearest other directions' log10 sigma_F90 (a tabulated
  prior interpolated over the sweep's grid, with no shape assumed).

Prints the RMS of the prediction errors in dex per colour bin (over its G bins), and how many
cells each way predicts to within 0.05 dex (near sigma_F90 a colour cell's fraction inside
changes by 0.50 per dex of width, 2.5 points per 0.05 dex: docs/prior_colour.md). A diagnosis for the choice of form; nothing here changes a prior.

Run: ``python docs/scripts/colour_form_loo.py COLOUR_RUN``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from mcsweep.experiments.f90_sweep.fit import direction_design
from mcsweep.galactic import unit_vector

N_NEIGHBOURS = 4
GOOD_DEX = 0.05


def predictions(grp: pd.DataFrame) -> pd.DataFrame:
    y = np.log10(grp["sigma_f90_mas"].to_numpy(float))
    l_deg, b_deg = grp["l_deg"].to_numpy(float), grp["b_deg"].to_numpy(float)
    a = direction_design(l_deg, b_deg)
    v = unit_vector(l_deg, b_deg)
    sep = np.arccos(np.clip(v @ v.T, -1.0, 1.0))
    eq14, near = np.full(len(y), np.nan), np.full(len(y), np.nan)
    for i in range(len(y)):  # one fit per left-out cell (48 per G bin): not a hot path
        keep = np.arange(len(y)) != i
        if keep.sum() >= 4 and np.linalg.matrix_rank(a[keep]) == 3:
            eq14[i] = a[i] @ np.linalg.lstsq(a[keep], y[keep], rcond=None)[0]
        order = np.argsort(np.where(keep, sep[i], np.inf))[:N_NEIGHBOURS]
        near[i] = y[order].mean()
    return pd.DataFrame({"eq14": eq14 - y, "neighbours": near - y})


def main(run: str) -> None:
    cells = pd.read_csv(Path(run) / "f90_colour_cells.csv")
    ok = cells[(cells["f90_flag"] == "ok") & np.isfinite(cells["sigma_f90_mas"])]
    rows = []
    for (c0, c1), by_colour in ok.groupby(["bp_rp_min", "bp_rp_max"], sort=True):
        errs = pd.concat([predictions(g) for _, g in by_colour.groupby("g_min") if len(g) >= 8])
        row = {"BP-RP": f"{c0:g}..{c1:g}", "cells": len(errs)}
        for form in ("eq14", "neighbours"):
            e = errs[form].dropna()
            row[f"{form} RMS dex"] = round(float(np.sqrt(np.mean(e**2))), 3)
            row[f"{form} within {GOOD_DEX} dex"] = f"{int((e.abs() < GOOD_DEX).sum())}/{len(e)}"
        rows.append(row)
    print(pd.DataFrame(rows).to_string(index=False))


if __name__ == "__main__":
    main(sys.argv[1])
