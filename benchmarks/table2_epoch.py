"""Table 2 before and after the reference-epoch change (Sect. 2.1,
``experiment.secondary.reference_epoch``): all 30 cells, with errors.

Usage::

    mcsweep experiment=secondary experiment.secondary.reference_epoch=star_mean hydra.run.dir=RUN_A
    mcsweep experiment=secondary hydra.run.dir=RUN_B          # reference_epoch=dataset_mean
    python benchmarks/table2_epoch.py RUN_A RUN_B > docs/table2_epoch.md

Per cell: ours with star_mean (before), ours with dataset_mean (after), the paper's
(Table 2, from :data:`mcsweep.experiments.secondary.table.PAPER_TABLE2`).

Uncertainties. Fractions: binomial 1 sigma, sqrt(f (1 - f) / n) with n the stars solved in
the cell. The paper's fractions get the same binomial sigma with our cell's n (the paper
does not give its subset sizes; its classes have the same 5e5 stars and ~4.4 retained
transits, so the subsets should be of similar size), plus its rounding to 0.1 %
(0.05 % / sqrt(3)). 90th percentiles: the order statistics at ranks n q -+ sqrt(n q (1-q))
(the binomial 1-sigma interval of the rank, q = 0.9), given as [lo, hi]; the paper's
percentiles are rounded to 2-3 digits and have no stated error. ``z`` is (after - paper)
over the combined sigma (fractions); ``ratio`` is after / paper (percentiles).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from mcsweep.experiments.global_solution.table import PAPER_G_CLASSES, SUBSETS, subset_masks
from mcsweep.experiments.secondary.table import PAPER_TABLE2, PRIORS, SOLUTION_COLUMNS

Q = 0.9
ROUND_FRAC = 0.0005 / np.sqrt(3.0)  # the paper's fractions are given to 0.1 %


def per_class(run: Path) -> dict[float, pd.DataFrame]:
    files = sorted((run / "secondary_chunks").glob("class*_stars*.parquet"))
    out: dict[float, list] = {}
    for f in files:
        g = int(re.match(r"class(\d+)_", f.name).group(1)) / 100.0
        out.setdefault(g, []).append(pd.read_parquet(f))
    return {g: pd.concat(p, ignore_index=True) for g, p in out.items()}


def cell(stars: pd.DataFrame, subset: str, stem: str) -> dict:
    sel = subset_masks(stars["n_fov"].to_numpy())[subset]
    inside = stars[f"inside_{stem}"].to_numpy()[sel]
    err = np.sort(stars[f"err_{stem}_mas"].to_numpy()[sel][inside >= 0].astype(np.float64))
    ok = inside >= 0
    n = int(ok.sum())
    f = float(np.mean(inside[ok] == 1))
    half = np.sqrt(n * Q * (1 - Q))
    lo, hi = (int(np.clip(np.floor(n * Q + s * half), 0, n - 1)) for s in (-1, 1))
    return {"n": n, "f": f, "sf": np.sqrt(f * (1 - f) / n), "p90": float(np.percentile(err, 100 * Q)),
            "p90_lo": err[lo], "p90_hi": err[hi]}


def main(before: Path, after: Path) -> str:
    runs = {"before": per_class(before), "after": per_class(after)}
    frac_rows, p90_rows = [], []
    for subset in SUBSETS:
        for prior in PRIORS:
            for i, g in enumerate(PAPER_G_CLASSES):
                b, a = (cell(runs[k][g], subset, SOLUTION_COLUMNS[prior]) for k in ("before", "after"))
                pf, pp = PAPER_TABLE2[(subset, prior)][0][i] / 100.0, PAPER_TABLE2[(subset, prior)][1][i]
                s_paper = np.hypot(np.sqrt(pf * (1 - pf) / a["n"]), ROUND_FRAC)
                z = (a["f"] - pf) / np.hypot(a["sf"], s_paper)
                name = f"{subset} | {prior} | {g:g}"
                frac_rows.append(f"| {name} | {a['n']} | {100 * b['f']:.2f} ± {100 * b['sf']:.2f} | "
                                 f"{100 * a['f']:.2f} ± {100 * a['sf']:.2f} | {100 * pf:.1f} ± {100 * s_paper:.2f} | "
                                 f"{z:+.1f} |")
                p90_rows.append(f"| {name} | {b['p90']:.3g} [{b['p90_lo']:.3g}, {b['p90_hi']:.3g}] | "
                                f"{a['p90']:.3g} [{a['p90_lo']:.3g}, {a['p90_hi']:.3g}] | {pp:g} | "
                                f"{a['p90'] / pp:.2f} |")
    lines = ["Fraction inside the 90 % ellipse:", "",
             "| subset | prior | G | n (after) | before: star_mean [%] | after: dataset_mean [%] | paper [%] | z |",
             "|---|---|---|---|---|---|---|---|", *frac_rows, "",
             "90th percentile of the position errors, [1-sigma interval]:", "",
             "| subset | prior | G | before: star_mean [mas] | after: dataset_mean [mas] | paper [mas] | after/paper |",
             "|---|---|---|---|---|---|---|", *p90_rows]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.stdout.write(main(Path(sys.argv[1]), Path(sys.argv[2])))
