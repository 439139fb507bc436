"""Did a change of the cells' draw move sigma_F90 by more than the draw's own noise?

Compares three finished sweep runs of one config: ``OLD`` and ``NEW`` (the old and the new
code at one seed) and ``OLD_OTHER_SEED`` (the old code at another seed: its distance from
``OLD`` is the seed-to-seed noise of the old draw). Prints, over the cells with sigma_F90 in
all three runs (colour cells included, per colour bin):

* the share of cells whose bootstrap intervals (sigma_F90_lo..hi) of ``NEW`` and ``OLD``
  overlap, and the same for ``OLD_OTHER_SEED`` against ``OLD``;
* the RMS difference of log10 sigma_F90 [dex], ``NEW - OLD`` against
  ``OLD_OTHER_SEED - OLD``;
* each run's comparison with the paper (``rms_dex.csv``: RMS of fit minus Eqs. 14-17 per G bin)
  and, with a colour axis, the RMS of the colour fit's forms (``colour_fit_forms.csv``).

Run: ``python docs/scripts/draw_change.py OLD OLD_OTHER_SEED NEW``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd


def _cells(run: Path) -> pd.DataFrame:
    parts = [pd.read_csv(run / "f90_cells.csv")]
    if (run / "f90_colour_cells.csv").exists():  # a sweep with a colour axis
        parts.append(pd.read_csv(run / "f90_colour_cells.csv"))
    df = pd.concat(parts, ignore_index=True)
    ok = np.isfinite(df["sigma_f90_mas"]) & (df["f90_flag"] == "ok")
    return df[ok].set_index("cell_id")


def _overlap(a: pd.DataFrame, b: pd.DataFrame) -> np.ndarray:
    lo_a, hi_a, lo_b, hi_b = (x[c] for x in (a, b) for c in ("sigma_f90_lo_mas", "sigma_f90_hi_mas"))
    return ((lo_a <= hi_b) & (lo_b <= hi_a)).to_numpy()


def _groups(df: pd.DataFrame) -> dict[str, np.ndarray]:
    out = {"all cells": np.ones(len(df), bool)}
    if "bp_rp_min" in df:
        blind = df["bp_rp_min"].isna().to_numpy()
        out["colour-blind"] = blind
        for (c0, c1), idx in df[~blind].groupby(["bp_rp_min", "bp_rp_max"]).indices.items():
            mask = np.zeros(len(df), bool)
            mask[np.flatnonzero(~blind)[idx]] = True
            out[f"BP-RP {c0:g} to {c1:g}"] = mask
    return out


def main(argv: list[str]) -> None:
    old_dir, other_dir, new_dir = map(Path, argv)
    old, other, new = _cells(old_dir), _cells(other_dir), _cells(new_dir)
    common = old.index.intersection(other.index).intersection(new.index)
    old, other, new = old.loc[common], other.loc[common], new.loc[common]
    print(f"{len(common)} cells with sigma_F90 (flag ok) in all three runs")
    print(f"{'cells':<22} {'n':>5} {'overlap new/old':>16} {'overlap seed/old':>17} "
          f"{'RMS new-old dex':>16} {'RMS seed-old dex':>17}")
    for label, m in _groups(old).items():
        if not m.any():
            continue
        d_new = np.log10(new["sigma_f90_mas"].to_numpy()[m] / old["sigma_f90_mas"].to_numpy()[m])
        d_seed = np.log10(other["sigma_f90_mas"].to_numpy()[m] / old["sigma_f90_mas"].to_numpy()[m])
        print(f"{label:<22} {m.sum():>5} {100 * _overlap(new[m], old[m]).mean():>15.1f}% "
              f"{100 * _overlap(other[m], old[m]).mean():>16.1f}% {np.sqrt(np.mean(d_new ** 2)):>16.4f} "
              f"{np.sqrt(np.mean(d_seed ** 2)):>17.4f}")
    print("\nRMS of the fit minus the paper's Eqs. 14-17 per G bin [dex] (rms_dex.csv)")
    rms = {name: pd.read_csv(d / "rms_dex.csv").set_index("g_bin")["rms_diff_dex"]
           for name, d in (("old", old_dir), ("old, other seed", other_dir), ("new", new_dir))}
    print(pd.DataFrame(rms).round(4).to_string())
    if (old_dir / "colour_fit_forms.csv").exists():
        print("\nRMS of the colour fit's forms per colour bin [dex] (colour_fit_forms.csv)")
        forms = {name: pd.read_csv(d / "colour_fit_forms.csv").set_index(["form", "colour_bin"])["rms_dex"]
                 for name, d in (("old", old_dir), ("old, other seed", other_dir), ("new", new_dir))}
        print(pd.DataFrame(forms).round(4).to_string())


if __name__ == "__main__":
    main(sys.argv[1:])
