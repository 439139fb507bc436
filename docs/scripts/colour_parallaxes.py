"""Why the colour prior misses on the real sky's red tercile: the parallaxes of the galaxy
model's stars against the Hipparcos stars' per |b| band and BP-RP tercile, G = 6-8.

The prior's width per colour comes from the model's stars of that colour; where the model's
parallax distribution is narrower than the real one, the width is too small. This prints,
per band and tercile (BP-RP < 0.56, 0.56-1.23, >= 1.23), the number of stars, the median and
the 90th percentile of the parallax, and the share with parallax > 10 mas (within ~100 pc:
dwarfs at G = 6-8), for a whole-sky draw of the model (seeded) and for the Hipparcos stars
(Hipparcos 2 parallaxes, Gaia DR3 BP-RP of the counterpart, the extra ``realsky``). A
diagnosis, not a calibration: nothing here feeds back into the model.

Run: ``python docs/scripts/colour_parallaxes.py``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from mcsweep.experiments.real_sky.experiment import colour_bin_of
from mcsweep.population import GalaxyModel, gaia_bright
from mcsweep.population.hipparcos import load_hipparcos

BANDS = [(0, 15), (15, 35), (35, 90)]


def summary(stars: pd.DataFrame, label: str) -> pd.DataFrame:
    rows = []
    cbin = colour_bin_of(stars["bp_rp"].to_numpy(float))
    absb = np.abs(stars["b"].to_numpy(float))
    plx = stars["parallax"].to_numpy(float)
    for b0, b1 in BANDS:
        for k, name in enumerate(("blue", "middle", "red")):
            m = (absb >= b0) & (absb < b1) & (cbin == k)
            p = plx[m]
            rows.append({"stars": label, "|b|": f"{b0}-{b1}", "tercile": name, "n": int(m.sum()),
                         "median plx": float(np.median(p)), "p90 plx": float(np.percentile(p, 90)),
                         "share plx > 10 mas": float(np.mean(p > 10))})
    return pd.DataFrame(rows)


def main() -> None:
    model = GalaxyModel().sample_sky(6.0, 8.0, np.random.default_rng(20261128))
    hip = load_hipparcos().assign(bp_rp=gaia_bright.hipparcos_match().hip_bp_rp)
    g = hip["phot_g_mean_mag"].to_numpy(float)
    hip = hip[(g >= 6.0) & (g < 8.0) & np.isfinite(hip["bp_rp"].to_numpy(float))]
    table = pd.concat([summary(model, "model"), summary(hip, "Hipparcos")])
    wide = table.pivot_table(index=["|b|", "tercile"], columns="stars",
                             values=["n", "median plx", "p90 plx", "share plx > 10 mas"], sort=False)
    print(wide.round(3).to_string())


if __name__ == "__main__":
    main()
