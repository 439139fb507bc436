"""Why the colour prior misses on the real sky's red tercile: the parallaxes of the galaxy
model's stars against the Hipparcos stars' per |b| band and BP-RP tercile, G = 6-8.

The prior's width per colour comes from the model's stars of that colour; where the model's
parallax distribution is narrower than the real one, the width is too small. This prints,
per band and tercile (BP-RP < 0.56, 0.56-1.23, >= 1.23), the number of stars, the median and
the 90th percentile of the parallax, the share with parallax > 10 mas (within ~100 pc:
dwarfs at G = 6-8) and the median total proper motion, for a whole-sky draw of the model
(seeded) and for the Hipparcos stars (Hipparcos 2 parallaxes and proper motions, Gaia DR3
BP-RP of the counterpart, the extra ``realsky``), with the model / Hipparcos ratios. A
validation, not a calibration: nothing here feeds back into the model.

Run: ``python docs/scripts/colour_parallaxes.py [--r03-5]`` (``--r03-5``: the galaxy model
besancon-r03-5, ``GalaxyModel(PARAMS_R03_5)``, instead of the default).
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd

from mcsweep.experiments.real_sky.experiment import colour_bin_of
from mcsweep.population import GalaxyModel, gaia_bright
from mcsweep.population.galaxy.model import PARAMS_R03_5
from mcsweep.population.hipparcos import load_hipparcos

BANDS = [(0, 15), (15, 35), (35, 90)]


def summary(stars: pd.DataFrame, label: str) -> pd.DataFrame:
    rows = []
    cbin = colour_bin_of(stars["bp_rp"].to_numpy(float))
    absb = np.abs(stars["b"].to_numpy(float))
    plx = stars["parallax"].to_numpy(float)
    pm = np.hypot(stars["pmra"].to_numpy(float), stars["pmdec"].to_numpy(float))
    for b0, b1 in BANDS:
        for k, name in enumerate(("blue", "middle", "red")):
            m = (absb >= b0) & (absb < b1) & (cbin == k)
            p = plx[m]
            rows.append({"stars": label, "|b|": f"{b0}-{b1}", "tercile": name, "n": int(m.sum()),
                         "median plx": float(np.median(p)), "p90 plx": float(np.percentile(p, 90)),
                         "share plx > 10 mas": float(np.mean(p > 10)),
                         "median pm": float(np.median(pm[m]))})
    return pd.DataFrame(rows)


def main() -> None:
    params = PARAMS_R03_5 if "--r03-5" in sys.argv[1:] else {}
    model = GalaxyModel(params).sample_sky(6.0, 8.0, np.random.default_rng(20261128))
    hip = load_hipparcos().assign(bp_rp=gaia_bright.hipparcos_match().hip_bp_rp)
    g = hip["phot_g_mean_mag"].to_numpy(float)
    hip = hip[(g >= 6.0) & (g < 8.0) & np.isfinite(hip["bp_rp"].to_numpy(float))]
    m, h = summary(model, "model"), summary(hip, "Hipparcos")
    wide = m[["|b|", "tercile"]].copy()
    for col in ("n", "median plx", "p90 plx", "median pm"):
        wide[f"{col} model"], wide[f"{col} Hip"] = m[col].to_numpy(), h[col].to_numpy()
        if col != "n":
            wide[f"{col} ratio"] = m[col].to_numpy() / h[col].to_numpy()
    rows = wide.round(3).astype(str).to_numpy().tolist()
    print("| " + " | ".join(wide.columns) + " |")
    print("|" + "---|" * len(wide.columns))
    for r in rows:
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
