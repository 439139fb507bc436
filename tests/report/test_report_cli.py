"""``mcsweep-report`` on directories that are not finished runs: one line, exit 2, nothing written."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


def _listing(d: Path) -> dict:
    return {p.relative_to(d).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns) for p in d.rglob("*")}


def _report(run_dir):
    r = subprocess.run([str(BIN / "mcsweep-report"), str(run_dir)], capture_output=True, text=True, timeout=120)
    return r, [ln for ln in r.stderr.splitlines() if ln.strip()]


@pytest.mark.parametrize("kind,missing", [("f90_sweep", "f90_cells.csv"), ("secondary", "table2.csv")])
def test_unfinished_run_says_what_is_missing_and_writes_nothing(tmp_path, kind, missing):
    # What a run leaves once its inputs are accepted and before its results exist
    # (prov.write(with_manifest=False) in the runners): provenance, a cell or chunk, Hydra's files.
    (tmp_path / ".hydra").mkdir()
    (tmp_path / ".hydra/config.yaml").write_text("seed: 1\n")
    (tmp_path / "provenance.json").write_text(json.dumps({"kind": kind, "config_hash": "x", "config": {},
                                                          "manifest": []}))
    (tmp_path / "cells").mkdir()
    (tmp_path / "cells/cell_a.parquet").write_bytes(b"PAR1")
    before = _listing(tmp_path)
    r, lines = _report(tmp_path)
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "unfinished" in lines[0] and missing in lines[0]
    assert _listing(tmp_path) == before


@pytest.mark.parametrize("content", ["{not json", json.dumps({"kind": "nonsense"})])
def test_damaged_provenance_is_one_line(tmp_path, content):
    (tmp_path / "provenance.json").write_text(content)
    r, lines = _report(tmp_path)
    assert r.returncode == 2 and len(lines) == 1 and "provenance.json" in lines[0], r.stderr
    assert os.listdir(tmp_path) == ["provenance.json"]
