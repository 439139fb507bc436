"""Monte Carlo precision of a sweep: the same sweep run with two seeds, cell by cell.

Two runs that differ only in ``seed`` draw independent stars and noise for every cell,
so the spread of ``log10 sigma_F90`` between them is twice the variance of one run's
Monte Carlo noise: the RMS difference divided by sqrt(2) is the noise of one run. The
per-cell bootstrap intervals (``sigma_f90_lo_mas``, ``sigma_f90_hi_mas``, 16-84 %) are an
independent estimate of the same noise; if both are right, about 52 % of the second
run's values fall inside the first run's intervals (two independent Gaussian draws,
interval +-1 sigma: P(|x2 - x1| < sigma) with x2 - x1 of width sqrt(2) sigma).

Run ``python -m mcsweep.validation.seed_spread RUN_A RUN_B`` (two run directories, each
with ``f90_cells.csv``); prints the table and writes nothing.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import UserInputError, report_user_error

__all__ = ["seed_spread", "EXPECTED_INSIDE"]

#: P(|x2 - x1| < sigma) for independent x1, x2 ~ N(mu, sigma^2): x2 - x1 has width
#: sqrt(2) sigma, so the probability is erf(1 / 2) = 0.5205.
EXPECTED_INSIDE = math.erf(0.5)


def seed_spread(f90_a: pd.DataFrame, f90_b: pd.DataFrame) -> pd.DataFrame:
    """Per G bin and overall: cells compared, RMS of log10(sigma_b / sigma_a) in dex, the
    median bootstrap half-width of run A in dex, and the fraction of B inside A's interval.

    Only cells flagged 'ok' in both runs enter.
    """
    key = ["cell_id"]
    m = f90_a.merge(f90_b, on=key, suffixes=("_a", "_b"))
    ok = m[(m["f90_flag_a"] == "ok") & (m["f90_flag_b"] == "ok")].copy()
    ok["diff_dex"] = np.log10(ok["sigma_f90_mas_b"] / ok["sigma_f90_mas_a"])
    ok["half_dex"] = 0.5 * np.log10(ok["sigma_f90_hi_mas_a"] / ok["sigma_f90_lo_mas_a"])
    ok["inside"] = (ok["sigma_f90_mas_b"] >= ok["sigma_f90_lo_mas_a"]) & (ok["sigma_f90_mas_b"]
                                                                         <= ok["sigma_f90_hi_mas_a"])

    def row(label, grp):
        half = grp["half_dex"][np.isfinite(grp["half_dex"])]
        return dict(g_bin=label, n_cells=len(grp), rms_diff_dex=float(np.sqrt(np.mean(grp["diff_dex"] ** 2))),
                    one_run_noise_dex=float(np.sqrt(np.mean(grp["diff_dex"] ** 2) / 2)),
                    median_half_width_dex=float(np.median(half)) if len(half) else np.nan,
                    fraction_b_inside_a=float(grp["inside"].mean()))

    rows = [row(f"{g0:g}-{g1:g}", grp) for (g0, g1), grp in ok.groupby(["g_min_a", "g_max_a"], sort=True)]
    rows.append(row("all", ok))
    return pd.DataFrame(rows)


_COLUMNS = ("cell_id", "g_min", "g_max", "f90_flag", "sigma_f90_mas", "sigma_f90_lo_mas", "sigma_f90_hi_mas")


def _f90_cells(run: Path) -> pd.DataFrame:
    path = run / "f90_cells.csv"
    try:
        table = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise UserInputError(f"{path}: cannot be read ({type(exc).__name__}); expected the directory of a "
                             "finished mcsweep sweep") from None
    missing = [c for c in _COLUMNS if c not in table.columns]
    if missing:
        raise UserInputError(f"{path} lacks the columns {missing}; expected f90_cells.csv of an mcsweep sweep "
                             "with sigma_F90 intervals")
    return table


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_a", type=Path)
    ap.add_argument("run_b", type=Path)
    args = ap.parse_args(argv)
    try:
        table = seed_spread(*(_f90_cells(run) for run in (args.run_a, args.run_b)))
    except UserInputError as exc:
        return report_user_error(exc, prog="mcsweep.validation.seed_spread")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"(expected fraction_b_inside_a for intervals that match the noise: {EXPECTED_INSIDE:.2f})")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
