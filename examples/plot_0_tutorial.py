"""
Tutorial: from install to a prior for your catalogue
====================================================

The whole path in one page, executed when this site is built: install, run a sweep, read
its report, turn its fit into a prior, annotate a catalogue with it, and solve sources seen
in a few transits.

**Install** (Python >= 3.11)::

    python3 -m venv .venv && . .venv/bin/activate && pip install .

``mcsweep hydra.run.dir=results/default`` is the main study (48 directions x 14 G bins, about
half a minute on 2 cores). Here a small sweep stands in for it so the page builds quickly:
five directions, G = 12-17, 2000 stars per cell.
"""

import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from astropy import units as u
from astropy.coordinates import SkyCoord

from mcsweep.prior import Prior
from mcsweep.prior.annotate import annotate_file
from mcsweep.prior.observations import (
    read_observations,
    solve_observations,
)

workdir = Path(tempfile.mkdtemp())
run_dir = workdir / "sweep"
done = subprocess.run(
    [
        str(Path(sys.executable).with_name("mcsweep")),
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
    check=True,
    capture_output=True,
    text=True,
)
print(textwrap.fill(done.stderr.strip().splitlines()[-1], 75))

# %%
# Reading the report
# ------------------
# ``report.md`` (and ``report.html``) opens with the headline: how far the fitted prior is from
# the paper's Eqs. 14-17, with our Monte Carlo uncertainty beside it. Every number in it is
# read from the run's tables (``f90_cells.csv``, ``coefficients.csv``, ...).
headline = [
    line
    for line in (run_dir / "report.md").read_text().splitlines()
    if line.startswith("- ")
]
print(
    "\n".join(
        textwrap.fill(h, 75, subsequent_indent="  ") for h in headline[:3]
    )
)

# %%
# Its figures are in ``figures/``: sigma_F90 per cell against the paper's formula, as in the
# paper's Fig. 4.
image = plt.imread(run_dir / "figures" / "fig4_magnitude.png")
fig, ax = plt.subplots(figsize=(7, 7 * image.shape[0] / image.shape[1]))
ax.imshow(image)
ax.set_axis_off()

# %%
# The prior
# ---------
# :meth:`~mcsweep.prior.Prior.from_run` reads the run's fit; :meth:`~mcsweep.prior.Prior.paper`
# is the paper's. Query it with sky coordinates in any frame and G. (A fit to five directions
# is rough, its coefficients' intervals wide; for real work use the default sweep's run.)
ours, paper = Prior.from_run(run_dir), Prior.paper()
stars = SkyCoord(
    ra=[10.0, 150.0, 266.4] * u.deg, dec=[40.0, 20.0, -29.0] * u.deg
)
g = np.array([13.0, 15.0, 16.5])
print("ours :", ours.sigma_parallax(stars, G=g).round(2))
print("paper:", paper.sigma_parallax(stars, G=g).round(2))
print("sigma_mu = R sigma_plx:", ours.sigma_pm(stars, G=g).round(1))

# %%
# Annotating your catalogue
# -------------------------
# Any table with Gaia archive columns (``ra, dec`` or ``l, b`` in degrees,
# ``phot_g_mean_mag``) gets ``sigma_f90_parallax`` and ``sigma_f90_pm``; the command is
# ``mcsweep-prior annotate stars.csv --out stars_prior.csv --run RUN_DIR``.
rng = np.random.default_rng(1)
pd.DataFrame(
    {
        "source_id": np.arange(1, 6),
        "ra": rng.uniform(0, 360, 5),
        "dec": np.degrees(np.arcsin(rng.uniform(-1, 1, 5))),
        "phot_g_mean_mag": rng.uniform(12, 17, 5),
    }
).to_csv(workdir / "stars.csv", index=False)
annotate_file(workdir / "stars.csv", workdir / "stars_prior.csv", ours)
print(
    pd.read_csv(workdir / "stars_prior.csv")
    .round(3)
    .to_string(index=False, line_width=75)
)

# %%
# Solving sources seen in a few transits
# --------------------------------------
# Their along-scan residuals per transit (``mcsweep-prior solve OBS --sources SOURCES --run
# RUN_DIR``; here the simulated ones of ``examples/prior_solve/``): with the prior each gets
# a five-parameter solution whose 90 % ellipse holds its true position 90 % of the time.
try:
    here = Path(__file__).resolve().parent
except NameError:
    # sphinx-gallery runs the script from the examples folder
    here = Path.cwd()
obs = read_observations(
    here / "prior_solve" / "observations.csv",
    here / "prior_solve" / "sources.csv",
)
solutions = solve_observations(obs, ours)
print(
    solutions[
        [
            "source_id",
            "n_transits",
            "parallax_mas",
            "parallax_error_mas",
            "ellipse_semi_major_mas",
        ]
    ]
    .head(6)
    .round(3)
    .to_string(index=False, line_width=75)
)
