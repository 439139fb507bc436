"""Runs that survive SIGKILL, and the same results on loky and on a Dask cluster."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

BIN = Path(sys.executable).parent
SMALL = [
    "sky=custom", "sky.directions=[[245.7,46.5],[30,-20],[120,5]]", "magnitudes.edges=[14,15,16,17]",
    "prior_grid.n=9", "cell.max_stars=300", "cell.min_stars=150", "execution.progress=false",
    "experiment.showcase.enabled=false",
]
KEYS = ["cell_id", "case", "at_f90", "sigma_prior_mas"]


def _sorted(path: Path) -> pd.DataFrame:
    return pd.read_parquet(path).sort_values(KEYS).reset_index(drop=True)


def _cmd(run_dir):
    return [str(BIN / "mcsweep"), f"hydra.run.dir={run_dir}", *SMALL]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref") / "run"
    r = subprocess.run(_cmd(out), capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.mark.slow
@pytest.mark.parametrize("kill_after_s", [1.0, 3.0, 6.0])
def test_sigkill_then_rerun_gives_identical_results(reference, tmp_path, kill_after_s):
    out = tmp_path / "run"
    proc = subprocess.Popen(_cmd(out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    time.sleep(kill_after_s)
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)  # the app and its loky workers, mid-write or not
    proc.wait(timeout=60)
    r = subprocess.run(_cmd(out), capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    pd.testing.assert_frame_equal(_sorted(out / "cells.parquet"), _sorted(reference / "cells.parquet"),
                                  check_exact=True)
    pd.testing.assert_frame_equal(pd.read_csv(out / "coefficients.csv"), pd.read_csv(reference / "coefficients.csv"),
                                  check_exact=True)
    assert not list((out / "cells").glob(".*.tmp"))  # temporaries of killed writes are not left as cells


@pytest.mark.slow
def test_dask_local_cluster_matches_loky_cell_by_cell(reference, tmp_path):
    pytest.importorskip("dask.distributed")
    from mcsweep.command.provenance import Provenance
    from mcsweep.command.validate import compose_config, to_config
    from mcsweep.experiments.f90_sweep.runner import run_sweep
    from omegaconf import OmegaConf

    cfg = compose_config([*SMALL, "execution=dask", "execution.n_jobs=2"])
    config, raw = to_config(cfg), OmegaConf.to_container(cfg, resolve=True)
    run_sweep(config, raw, tmp_path, prov=Provenance(tmp_path, raw, kind="f90_sweep"))
    dask_cells = sorted((tmp_path / "cells").glob("cell_*.parquet"))
    ref_cells = sorted((reference / "cells").glob("cell_*.parquet"))
    assert [p.name for p in dask_cells] == [p.name for p in ref_cells] and len(ref_cells) == 9
    for a, b in zip(dask_cells, ref_cells):
        pd.testing.assert_frame_equal(pd.read_parquet(a), pd.read_parquet(b), obj=a.name, check_exact=True)
