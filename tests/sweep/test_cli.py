"""The ``mcsweep`` entry point end to end: outputs, resume, n_jobs invariance, bad input."""

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

BIN = Path(sys.executable).parent
SMALL = [
    "sky=custom", "sky.directions=[[245.7,46.5],[30,-20],[120,5],[300,60]]",
    "magnitudes.edges=[13,14,15,16,17]", "prior_grid.n=13",
    "cell.max_stars=300", "cell.min_stars=150", "execution.progress=false",
]


def run(args, **kw):
    return subprocess.run([str(BIN / "mcsweep"), *args], capture_output=True, text=True, timeout=600, **kw)


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "sweep"
    # The usual umask, stated so the mode test below does not depend on the caller's shell.
    r = run([f"hydra.run.dir={out}", *SMALL, "execution.n_jobs=2"], umask=0o022)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.mark.slow
def test_small_sweep_writes_cells_coefficients_and_report(small_run):
    cells = sorted((small_run / "cells").glob("cell_*.parquet"))
    assert len(cells) == 4 * 4
    for name in ("cells.parquet", "coefficients.csv", "f90_cells.csv", "rms_dex.csv", "report.md",
                 "report.html", "provenance.json", "figures/fig1_curves.png", "figures/fig3_cases.png"):
        assert (small_run / name).exists(), name
    coef = pd.read_csv(small_run / "coefficients.csv")
    assert list(coef.columns) == ["term", "fitted", "paper", "difference"] and len(coef) == 9
    table = pd.read_parquet(small_run / "cells.parquet")
    assert set(table["case"]) == {"one", "two", "two_diluted", "four", "eight"}
    assert table["fraction_inside"].between(0, 1).all()
    report = (small_run / "report.md").read_text()
    assert "Provenance" in report


@pytest.mark.slow
def test_report_summarises_the_manifest_which_stays_in_provenance(small_run):
    report = (small_run / "report.md").read_text()
    # The report summarises the computation's files as they were when it was written
    # (the report stage's own outputs come after it).
    manifest = [m for m in json.loads((small_run / "provenance.json").read_text())["manifest"]
                if m["path"].startswith(("cells/", "cells.parquet", "showcase/"))]
    assert len(manifest) == 4 * 4 + 1 + len(list((small_run / "showcase").glob("*")))
    assert "cells/cell_" not in report  # no file-by-file listing in the report
    assert f"Result files of the computation (before this report): {len(manifest)} files" in report
    digest = hashlib.sha256("\n".join(sorted(f"{m['path']}:{m['sha256']}" for m in manifest)).encode())
    assert digest.hexdigest()[:16] in report


@pytest.mark.slow
def test_result_files_are_readable_by_group_and_others_under_umask_022(small_run):
    files = [p for p in small_run.rglob("*") if p.is_file()]
    assert len(files) > 20
    private = [str(p.relative_to(small_run)) for p in files if (p.stat().st_mode & 0o777) != 0o644]
    assert not private, private


@pytest.mark.slow
def test_rerun_skips_finished_cells_and_njobs_does_not_matter(small_run, tmp_path):
    before = {p.name: p.stat().st_mtime_ns for p in (small_run / "cells").glob("*.parquet")}
    r = run([f"hydra.run.dir={small_run}", *SMALL, "execution.n_jobs=2"])
    assert r.returncode == 0, r.stderr[-2000:]
    after = {p.name: p.stat().st_mtime_ns for p in (small_run / "cells").glob("*.parquet")}
    assert before == after  # nothing recomputed
    one = tmp_path / "one"
    r = run([f"hydra.run.dir={one}", *SMALL, "execution.n_jobs=1"])
    assert r.returncode == 0, r.stderr[-2000:]
    a = pd.read_parquet(small_run / "cells.parquet").sort_values(["cell_id", "case", "sigma_prior_mas"])
    b = pd.read_parquet(one / "cells.parquet").sort_values(["cell_id", "case", "sigma_prior_mas"])
    pd.testing.assert_frame_equal(a.reset_index(drop=True), b.reset_index(drop=True), check_exact=True)


@pytest.mark.slow
def test_changed_config_in_same_run_dir_is_refused(small_run):
    r = run([f"hydra.run.dir={small_run}", *SMALL, "confidence=0.8"])
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.strip().splitlines() if ln]
    assert len(lines) == 1 and "different config" in lines[0] and "confidence" in lines[0]


@pytest.mark.parametrize("bad", [
    ["confidence=1.5"], ["cell.beam_radius_deg=-1"], ["sky=nowhere"], ["magnitudes.edges=[24,26]"],
    ["population=catalogue", "population.path=/nonexistent/stars.csv"],
])
def test_bad_overrides_exit_2_with_one_line_and_no_output(tmp_path, bad):
    out = tmp_path / "bad"
    r = run([f"hydra.run.dir={out}", *bad])
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    lines = [ln for ln in r.stderr.strip().splitlines() if ln]
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.stderr
    assert not out.exists()


@pytest.mark.slow
def test_dask_info_lines_go_to_the_log_file_not_the_terminal(tmp_path):
    pytest.importorskip("dask.distributed")
    out = tmp_path / "dask"
    r = run([f"hydra.run.dir={out}", "sky=custom", "sky.directions=[[245.7,46.5]]", "magnitudes.edges=[14,15]",
             "prior_grid.n=7", "cell.max_stars=100", "cell.min_stars=50", "execution=dask",
             "execution.n_jobs=2", "execution.progress=false"])
    assert r.returncode == 0, r.stderr[-2000:]
    terminal = r.stdout + r.stderr
    assert "distributed." not in terminal, terminal[:2000]
    assert terminal.strip().splitlines()[-1].startswith("mcsweep: results in")
    log = "".join(p.read_text() for p in out.glob("*.log"))
    assert "distributed.scheduler" in log  # kept in the run's log
