"""Per-source comparison of mcsweep's source update with gaiasupdate's and AGIS's (docs/guide/dr4_epochs.md).

Prints, for every source of the vendored DR4-format files, mcsweep's no-prior solution minus
gaiasupdate 0.1.2's (``tests/data/gaiasupdate/reference_solutions.csv``) and minus AGIS's
(the results shipped with gaiasupdate's test data), in units of the formal error, and the
same for gaiasupdate minus AGIS.

Run from the repository root: ``python docs/scripts/dr4_comparison.py``.
"""

from importlib.resources import files
from pathlib import Path

import numpy as np
import pandas as pd

from mcsweep.astrometry.epoch_astrometry import ccd_observations
from mcsweep.astrometry.solve import solve_no_prior
from mcsweep.astrometry.source_update import source_normals
from mcsweep.tables import read_table

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "gaiasupdate"
SAMPLE = Path(str(files("mcsweep") / "data" / "epoch_astrometry"))
REF = pd.read_csv(DATA / "reference_solutions.csv")
PAR = ("parallax_mas", "pmra_mas_yr", "pmdec_mas_yr")
AGIS = ("varpi", "muAlphaStar", "muDelta")
CASES = [("sample_epoch_astrometry.parquet", SAMPLE / "sample_epoch_astrometry.parquet",
          SAMPLE / "sample_agis_results.parquet", "5p", "agis_excess_noise"),
         ("constrained_colour/1_archive_epoch_astro.parquet", DATA / "constrained_colour/1_archive_epoch_astro.parquet",
          DATA / "constrained_colour/1_archive_source_update_results.parquet", "6p", "file_excess_noise"),
         ("constrained_colour/2_epoch_astrometry.parquet", DATA / "constrained_colour/2_epoch_astrometry.parquet",
          DATA / "constrained_colour/2_agis_source_update_results.parquet", "6p", "file_excess_noise")]


def ours(path, model):
    sn = source_normals(ccd_observations(read_table(path), need_colour=model == "6p"), model=model)
    sol = solve_no_prior(sn.N, sn.b, max_condition=np.inf)
    return pd.DataFrame(sol.x[:, 2:], index=sn.source_id, columns=list(PAR))


def main():
    rows = []
    for name, epoch, agis_file, model, variant in CASES:
        got = ours(epoch, model)
        gs = REF[(REF["file"] == name) & (REF["model"] == model) & (REF["variant"] == variant)].set_index("source_id")
        agis = pd.read_parquet(agis_file).set_index("sourceId")
        for sid in got.index:
            row = {"file": name.split("/")[-1], "source_id": sid, "model": model, "G": agis.loc[sid].get("gMag", np.nan)}
            for p, a in zip(PAR, AGIS):
                sigma = agis.loc[sid, a + "Error"]
                row[f"{a} mcsweep-gs"] = (got.loc[sid, p] - gs.loc[sid, p]) / gs.loc[sid, p + "_error"]
                row[f"{a} mcsweep-AGIS"] = (got.loc[sid, p] - agis.loc[sid, a]) / sigma
                row[f"{a} gs-AGIS"] = (gs.loc[sid, p] - agis.loc[sid, a]) / sigma
            rows.append(row)
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 250, "display.max_columns", 20, "display.float_format", "{:.2g}".format):
        print(table.to_string(index=False))


if __name__ == "__main__":
    main()
