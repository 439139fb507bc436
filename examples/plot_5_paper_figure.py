"""
Draw the paper's Fig. 1 from a run
==================================

Every sweep that includes the Table 1 beam (l = 24.6 deg, b = 46.5 deg, G = 15 +- 0.5)
writes its curves to ``showcase/``: per observation case and prior, the fraction of
stars inside the P ellipse, the P-th percentile of the actual position errors and the
median semi-major axis of the ellipse. The paper's Fig. 1 is the two-transit case of
those curves; sigma_F90 is where the percentile of the errors meets the semi-major axis.
"""

import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

run_dir = Path(tempfile.mkdtemp()) / "beam"
command = Path(sys.executable).with_name("mcsweep")
subprocess.run(
    [
        str(command),
        "sky=single",
        "magnitudes=g15",
        "cell.min_stars=4000",
        "cell.max_stars=4000",
        "cell.n_bootstrap=20",
        "execution.n_jobs=1",
        "execution.progress=false",
        f"hydra.run.dir={run_dir}",
    ],
    capture_output=True,
    text=True,
    check=True,
)

curves = pd.concat(
    pd.read_parquet(p)
    for p in sorted((run_dir / "showcase").glob("cell_*[0-9].parquet"))
)
two = curves[(curves["case"] == "two") & ~curves["at_f90"]]
f90 = float(curves["sigma_f90_mas"].iloc[0])
lo, hi = (
    curves["sigma_f90_lo_mas"].iloc[0],
    curves["sigma_f90_hi_mas"].iloc[0],
)
print(f"sigma_F90 of the Table 1 beam: {f90:.3g} mas [{lo:.3g}, {hi:.3g}]")

fig, ax = plt.subplots(figsize=(6, 4.5))
ax.plot(
    two["sigma_prior_mas"],
    two["p_error_mas"],
    "b--",
    label="90th percentile of actual errors",
)
ax.plot(
    two["sigma_prior_mas"],
    two["median_semi_major_mas"],
    "r-",
    label="semi-major axis of the 90 % ellipse (median)",
)
ax.axvline(
    f90, color="k", lw=1, label=rf"$\sigma_{{F90}}$ = {f90:.3g} mas"
)
ax.set_xscale("log")
ax.set_yscale("log")
ax.set_xlabel(r"parallax prior $\sigma_{\varpi,p}$ [mas]")
ax.set_ylabel("position error / uncertainty [mas]")
ax.set_title("Table 1 beam, two distinct transits (paper Fig. 1)")
ax.legend(fontsize=8)
fig.tight_layout()
