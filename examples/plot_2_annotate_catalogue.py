"""
Annotate a small catalogue
==========================

``mcsweep-prior annotate`` adds the columns ``sigma_f90_parallax`` [mas] and
``sigma_f90_pm`` [mas/yr] to a catalogue with Gaia archive column names (``ra, dec`` or
``l, b`` in degrees, ``phot_g_mean_mag``); every other column is kept. The same from
Python is :func:`mcsweep.prior.annotate.annotate_file`.
"""

import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd

from mcsweep.prior import Prior
from mcsweep.prior.annotate import annotate_file

workdir = Path(tempfile.mkdtemp())
rng = np.random.default_rng(2015)
catalogue = pd.DataFrame(
    {
        "source_id": np.arange(1, 9),
        "ra": rng.uniform(0, 360, 8),
        "dec": np.degrees(np.arcsin(rng.uniform(-1, 1, 8))),
        "phot_g_mean_mag": rng.uniform(8, 20, 8),
    }
)
catalogue.to_csv(workdir / "stars.csv", index=False)

# %%
# From Python: the number of rows written comes back.
n = annotate_file(
    workdir / "stars.csv", workdir / "stars_prior.csv", Prior.paper()
)
print(n, "rows annotated")
print(
    pd.read_csv(workdir / "stars_prior.csv")
    .round(3)
    .to_string(index=False, line_width=75)
)

# %%
# The command does the same (``--paper`` or ``--run RUN_DIR`` for a sweep's fit); Parquet
# and CSV are streamed in batches, so memory stays flat for any size.
command = Path(sys.executable).with_name("mcsweep-prior")
done = subprocess.run(
    [
        str(command),
        "annotate",
        str(workdir / "stars.csv"),
        "--out",
        str(workdir / "stars_prior.parquet"),
        "--paper",
    ],
    capture_output=True,
    text=True,
    check=True,
)
print(textwrap.fill((done.stdout or done.stderr).strip(), 75))
columns = pd.read_parquet(workdir / "stars_prior.parquet").columns
print(textwrap.fill(str(columns.tolist()), 75))
