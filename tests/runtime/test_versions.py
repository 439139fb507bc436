"""Cells remember the code version that computed them; a resume refuses another version's cells.

Formerly, resuming after an upgrade reused old cells silently and then recorded the new
commit for all of them.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from mcsweep.errors import UserInputError
from mcsweep.runtime.store import ResultStore
from mcsweep.runtime.version import code_version

BIN = Path(sys.executable).parent
OLD = "mcsweep 0.0.1 (git 0123456789ab)"


def _refake_version(path: Path, version: str) -> None:
    table = pq.read_table(path)
    meta = json.loads(table.schema.metadata[b"mcsweep"])
    meta["code_version"] = version
    pq.write_table(table.replace_schema_metadata({**table.schema.metadata, b"mcsweep": json.dumps(meta).encode()}),
                   path)


def test_store_refuses_a_cell_of_another_version_naming_both(tmp_path):
    df = pd.DataFrame({"x": np.arange(3.0)})
    ResultStore(tmp_path, "h", version=OLD).write("c1", df)
    with pytest.raises(UserInputError) as err:
        ResultStore(tmp_path, "h").read("c1")
    msg = str(err.value)
    assert OLD in msg and code_version() in msg and "resume.accept_other_versions=true" in msg
    kept = ResultStore(tmp_path, "h", accept_other_versions=True)
    pd.testing.assert_frame_equal(kept.read("c1"), df, check_exact=True)
    assert kept.versions_read == {OLD: 1}


def test_store_treats_a_cell_without_a_version_as_another_version(tmp_path):
    ResultStore(tmp_path, "h").write("c1", pd.DataFrame({"x": [1.0]}))
    path = tmp_path / "c1.parquet"
    table = pq.read_table(path)
    meta = json.loads(table.schema.metadata[b"mcsweep"])
    del meta["code_version"]
    pq.write_table(table.replace_schema_metadata({b"mcsweep": json.dumps(meta).encode()}), path)
    with pytest.raises(UserInputError, match="too old to record its version"):
        ResultStore(tmp_path, "h").read("c1")


@pytest.mark.slow
def test_resume_after_an_upgrade_refuses_old_cells_unless_asked(tmp_path):
    rng = np.random.default_rng(7)
    n = 400
    cat = tmp_path / "stars.csv"
    pd.DataFrame(dict(ra=rng.uniform(156, 159, n), dec=rng.uniform(-1.5, 1.5, n), parallax=rng.uniform(0.1, 3, n),
                      pmra=rng.normal(0, 5, n), pmdec=rng.normal(0, 5, n),
                      phot_g_mean_mag=rng.uniform(14.5, 15.5, n))).to_csv(cat, index=False)
    out = tmp_path / "run"
    args = [str(BIN / "mcsweep"), f"hydra.run.dir={out}", "sky=single", "magnitudes.edges=[14.5,15,15.5]",
            "prior_grid.n=5", "execution.n_jobs=1", "cell.min_stars=50",
            "experiment.showcase.enabled=false", "population=catalogue", f"population.path={cat}"]
    r = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    # Progress is on and stderr is a pipe: whole lines, no carriage-return redraws (item 7).
    assert "\r" not in r.stderr and "cells: 2/2 cells (100 %)" in r.stderr, r.stderr
    assert "transits: scanning law over 1 direction," in r.stderr and "FoV transits found in" in r.stderr
    cells = sorted((out / "cells").glob("cell_*.parquet"))
    assert len(cells) == 2
    _refake_version(cells[0], OLD)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}

    r = subprocess.run(args, capture_output=True, text=True, timeout=300)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2, r.stderr[-3000:]
    assert len(lines) == 1 and OLD in lines[0] and code_version() in lines[0], r.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before  # incl. provenance.json

    r = subprocess.run([*args, "resume.accept_other_versions=true"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["cell_code_versions"] == {OLD: 1, code_version(): 1}
