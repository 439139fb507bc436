"""A refused run removes exactly what it created: never the user's files, never an earlier run's.

The bug this guards against: ``mcsweep hydra.run.dir=. population=catalogue
population.path=typo.fits`` in a folder of the user's own files printed the right error and
then deleted the folder.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from mcsweep.command.rundir import Snapshot

BIN = Path(sys.executable).parent
OLD_NS = 1_577_836_800_000_000_000  # 2020-01-01, so a rewrite cannot keep the same mtime by chance


def _plant(root: Path, files: dict[str, bytes]) -> None:
    for rel, data in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)
        os.utime(p, ns=(OLD_NS, OLD_NS))


def _state(root: Path) -> dict:
    """Every path under root with its bytes (files) and mtime."""
    out = {}
    for p in sorted(root.rglob("*")):
        st = p.lstat()
        out[p.relative_to(root).as_posix()] = (p.read_bytes() if p.is_file() else None, st.st_mtime_ns)
    return out


def _mcsweep(cwd: Path, *args):
    r = subprocess.run([str(BIN / "mcsweep"), *args], capture_output=True, text=True, timeout=300, cwd=cwd)
    return r, [ln for ln in r.stderr.splitlines() if ln.strip()]


USER_FILES = {"figures/my_plot.png": b"\x89PNG mine", "report.md": b"# my notes\n", "analysis.log": b"my log\n",
              "cells/mine.txt": b"mine\n", ".hydra/config.yaml": b"my: config\n"}


def test_refused_run_in_a_folder_of_user_files_touches_none_of_them(tmp_path):
    """The original bug's case: files named like our outputs, run dir '.', a typo in the catalogue path."""
    _plant(tmp_path, USER_FILES)
    before = _state(tmp_path)
    r, lines = _mcsweep(tmp_path, "hydra.run.dir=.", "population=catalogue", "population.path=typo.fits")
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert _state(tmp_path) == before
    assert tmp_path.is_dir()


def test_refused_catalogue_in_a_folder_without_name_clashes_keeps_every_file(tmp_path):
    """No clash with our output names: the job starts, Hydra writes, the catalogue is refused."""
    files = {"notes.txt": b"n\n", "analysis.log": b"my log\n", ".hydra/config.yaml": b"my: config\n",
             ".hydra/hydra.yaml": b"h: 1\n", "sub/deep/x.dat": b"\0\1"}
    _plant(tmp_path, files)
    before = _state(tmp_path)
    r, lines = _mcsweep(tmp_path, "hydra.run.dir=.", "population=catalogue", "population.path=typo.fits")
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1 and "typo.fits" in lines[0], r.stderr
    assert _state(tmp_path) == before  # Hydra's .hydra/*.yaml and cli.log rewrites undone too


def test_refused_config_in_an_existing_run_keeps_its_hydra_files(tmp_path):
    """Item 2: Hydra rewrites .hydra/ before the job refuses a different config; it is put back."""
    run = tmp_path / "run"
    prov = {"kind": "f90_sweep", "config_hash": "0123456789abcdef", "config": {"confidence": 0.95}}
    _plant(run, {".hydra/config.yaml": b"confidence: 0.95\n", ".hydra/hydra.yaml": b"hydra: {}\n",
                 ".hydra/overrides.yaml": b"- confidence=0.95\n", "cli.log": b"[old] run\n",
                 "provenance.json": json.dumps(prov).encode(), "cells/cell_a.parquet": b"PAR1"})
    before = _state(run)
    r, lines = _mcsweep(tmp_path, f"hydra.run.dir={run}", "sky=single", "magnitudes=g15", "confidence=0.8")
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1 and "different config" in lines[0], r.stderr
    assert _state(run) == before


def test_refused_run_removes_the_directories_it_created_and_no_more(tmp_path):
    r, lines = _mcsweep(tmp_path, f"hydra.run.dir={tmp_path}/a/b/c", "population=catalogue",
                        "population.path=typo.fits")
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert list(tmp_path.iterdir()) == []


def test_snapshot_undo_removes_only_new_paths_and_restores_rewritten_files(tmp_path):
    _plant(tmp_path, {"keep.txt": b"k", ".hydra/config.yaml": b"old", "cells/mine.txt": b"m",
                      "provenance.json": b"{}", "job.log": b"line 1\n"})
    before = _state(tmp_path)
    snap = Snapshot.take(tmp_path)
    (tmp_path / ".hydra/config.yaml").write_bytes(b"new")
    (tmp_path / ".hydra/hydra.yaml").write_bytes(b"new")
    (tmp_path / "provenance.json").write_bytes(b'{"new": 1}')
    with open(tmp_path / "job.log", "a") as f:
        f.write("line 2\n")
    (tmp_path / "cells/cell_1.parquet").write_bytes(b"x")
    (tmp_path / "figures").mkdir()
    (tmp_path / "figures/fig.png").write_bytes(b"x")
    assert snap.new_paths() == [".hydra/hydra.yaml", "cells/cell_1.parquet", "figures", "figures/fig.png"]
    snap.undo()
    assert _state(tmp_path) == before


def test_snapshot_of_a_missing_directory_removes_it_and_its_new_parents(tmp_path):
    (tmp_path / "other").mkdir()
    snap = Snapshot.take(tmp_path / "x/y/run")
    (tmp_path / "x/y/run/.hydra").mkdir(parents=True)
    (tmp_path / "x/y/run/.hydra/config.yaml").write_text("c")
    snap.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other"]


@pytest.mark.parametrize("scope", ["job0", "job1"])
def test_snapshot_undo_of_one_job_leaves_its_siblings(tmp_path, scope):
    _plant(tmp_path, {"job1/old.txt": b"o"})
    snap = Snapshot.take(tmp_path)
    for job in ("job0", "job1"):
        (tmp_path / job).mkdir(exist_ok=True)
        (tmp_path / job / "new.txt").write_text("n")
    snap.undo(tmp_path / scope)
    other = "job1" if scope == "job0" else "job0"
    assert (tmp_path / other / "new.txt").exists()
    assert not (tmp_path / scope / "new.txt").exists()
    assert (tmp_path / "job1/old.txt").read_bytes() == b"o"


def test_tree_too_large_to_list_loses_only_new_top_level_names(tmp_path, monkeypatch):
    import mcsweep.command.rundir as rundir

    _plant(tmp_path, {f"data/f{i}.txt": b"d" for i in range(20)})
    _plant(tmp_path, {".hydra/config.yaml": b"old", "keep.txt": b"k"})
    monkeypatch.setattr(rundir, "MAX_ENTRIES", 5)
    snap = Snapshot.take(tmp_path)
    assert snap.paths is None
    (tmp_path / ".hydra/config.yaml").write_bytes(b"new")
    (tmp_path / "cli.log").write_text("new log")
    (tmp_path / "cells").mkdir()
    (tmp_path / "cells/c.parquet").write_bytes(b"x")
    (tmp_path / "data/new.txt").write_text("cannot be told from the user's")
    snap.undo()
    assert not (tmp_path / "cli.log").exists() and not (tmp_path / "cells").exists()
    assert (tmp_path / ".hydra/config.yaml").read_bytes() == b"old"
    assert len(list((tmp_path / "data").iterdir())) == 21  # kept: unlisted trees err on keeping
    assert (tmp_path / "keep.txt").read_bytes() == b"k"
