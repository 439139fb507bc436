"""
Run a tiny sweep and read its results
=====================================

The ``mcsweep`` command with a few overrides: five directions of your own, five G bins from
G = 12 to 17, 2000 stars per cell, one worker (about 10 s). A run directory holds tidy tables (read them with
pandas), the fit (:func:`mcsweep.experiments.f90_sweep.fit.read_fit`), the prior maps and
``provenance.json``.
"""

import json
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import pandas as pd

from mcsweep.experiments.f90_sweep.fit import read_fit

run_dir = Path(tempfile.mkdtemp()) / "tiny"
command = Path(sys.executable).with_name("mcsweep")
done = subprocess.run(
    [
        str(command),
        "sky=custom",
        "sky.directions=[[0,30],[180,-30],[90,60],[270,-10],[45,5]]",
        "magnitudes.edges=[12,13,14,15,16,17]",
        "cell.min_stars=2000",
        "cell.max_stars=2000",
        "cell.n_bootstrap=20",
        "execution.n_jobs=1",
        "execution.progress=false",
        f"hydra.run.dir={run_dir}",
    ],
    capture_output=True,
    text=True,
    check=True,
)
print(textwrap.fill(done.stderr.strip().splitlines()[-1], 75))
print(textwrap.fill(str(sorted(p.name for p in run_dir.iterdir())), 75))

# %%
# sigma_F90 per cell next to the paper's formula (the sweep also simulated the Table 1
# beam, l = 245.7 deg, b = 46.5 deg, for the report's Figs. 1-3).
f90 = pd.read_csv(run_dir / "f90_cells.csv")
print(
    f90[
        [
            "l_deg",
            "b_deg",
            "g",
            "n_stars",
            "sigma_f90_mas",
            "sigma_f90_lo_mas",
            "sigma_f90_hi_mas",
            "paper_sigma_f90_mas",
            "f90_flag",
        ]
    ]
    .round(3)
    .to_string(index=False, line_width=75)
)

# %%
# The fit of Eqs. 15-17 (Sect. 3.4) to these 25 cells, next to the paper's coefficients, with
# 16-84 % bootstrap intervals. Five directions pin Eq. 14's three terms per G bin only loosely,
# so the intervals are wide and hold the paper's values; the default sweep (48 directions x 14
# G bins) is what the paper's fit is compared with. With fewer than four G bins the
# polynomials in G cannot be fitted and ``coefficients.csv`` holds NaN.
fit = read_fit(run_dir)
print(
    fit.coefficients[["term", "fitted", "fitted_lo", "fitted_hi", "paper"]]
    .round(4)
    .to_string(index=False, line_width=75)
)

# %%
# Provenance: the resolved config, its hash, the code version and the seeds.
prov = json.loads((run_dir / "provenance.json").read_text())
for key in (
    "kind",
    "config_hash",
    "mcsweep_version",
    "galaxy_model_version",
    "git_commit",
):
    print(f"{key}: {prov[key]}")
print(textwrap.fill(prov.get("seeds", {}).get("cells", ""), 75))
