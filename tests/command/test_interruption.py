"""Ctrl-C and a full disk, through each command: one line, exit 130 / 1, nothing half-written, resume.

The full disk is injected at the write itself: the store's (or the writer's) atomic write
puts half the bytes into its temporary file and then fails as a real ``write()`` does,
``OSError(ENOSPC)`` naming no file. Commands run in-process (one job, so every write
happens where the patch is), except for Ctrl-C: a real ``mcsweep`` process in its own
process group gets SIGINT sent to the whole group, as a terminal does, so its loky
workers get it too.
"""

import errno
import logging
import multiprocessing
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from mcsweep import cli, prior_cli
from mcsweep.report import cli as report_cli
from mcsweep.runtime import drawing as drawing_mod
from mcsweep.runtime import store as store_mod
# The command modules, imported before any test patches the store's writes (mcsweep.cli
# imports them only when a job runs): those that import atomic_write_bytes by name keep the real one.
from mcsweep.experiments.f90_sweep import runner as _f90_runner  # noqa: F401
from mcsweep.experiments.primary import runner as _primary_runner  # noqa: F401
from mcsweep.experiments.real_sky import runner as _real_sky_runner  # noqa: F401
from mcsweep.experiments.secondary import runner as _secondary_runner  # noqa: F401
from mcsweep.experiments.f90_sweep.runner import run_sweep
from mcsweep.command.provenance import Provenance
from mcsweep.command.validate import compose_config, to_config

BIN = Path(sys.executable).parent
ROOT = Path(__file__).resolve().parents[2]
#: 3 directions x 5 G bins of 100-200 stars: a few seconds, long enough to be interrupted.
SMALL = ["sky=custom", "sky.directions=[[245.7,46.5],[30,-20],[120,5]]", "magnitudes.edges=[13,14,15,16,17,18]",
         "prior_grid.n=9", "cell.max_stars=200", "cell.min_stars=100", "execution.progress=false",
         "experiment.showcase.enabled=false"]
N_CELLS = 15
KEYS = ["cell_id", "case", "at_f90", "sigma_prior_mas"]
RESUME = "run the same command to resume"
DISK_FULL = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _sorted(path: Path) -> pd.DataFrame:
    return pd.read_parquet(path).sort_values(KEYS).reset_index(drop=True)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The same sweep, uninterrupted (cells only: the report does not change them)."""
    out = tmp_path_factory.mktemp("reference")
    cfg = compose_config([*SMALL, "execution.n_jobs=1"])
    raw = OmegaConf.to_container(cfg, resolve=True)
    run_sweep(to_config(cfg), raw, out, prov=Provenance(out, raw, kind="f90_sweep"))
    return out


def _fail_store_write(monkeypatch, after: int, exc: BaseException, match=lambda p: True):
    """Let ``after`` matching atomic writes of the store through, then fail the next ones midway.

    Modules that import ``atomic_write_bytes`` by name keep the real one: every command
    module is imported above, before any test patches.
    """
    real = store_mod.atomic_write_bytes
    seen = []

    def write(path, data):
        if not match(Path(path)):
            return real(path, data)
        seen.append(path)
        if len(seen) <= after:
            return real(path, data)

        def half_then_fail(tmp):
            tmp.write_bytes(data[: len(data) // 2])
            raise exc

        return store_mod.atomic_write_via(path, half_then_fail)

    monkeypatch.setattr(store_mod, "atomic_write_bytes", write)


def _mcsweep(monkeypatch, capsys, args) -> tuple[int, list[str]]:
    monkeypatch.setattr(sys, "argv", ["mcsweep", *map(str, args)])
    # Hydra's job logging puts handlers on the captured stderr, which pytest closes after
    # the test: later tests that log or flush would write to a closed file. Put the root
    # logger's handlers back as they were.
    root = logging.getLogger()
    before = list(root.handlers)
    try:
        cli.main()
        code = 0
    except SystemExit as e:
        code = e.code
    finally:
        for h in [h for h in root.handlers if h not in before]:
            root.removeHandler(h)
        for h in [h for h in before if h not in root.handlers]:
            root.addHandler(h)
    err = capsys.readouterr().err
    return code, [ln for ln in err.splitlines() if ln.strip()]


def _temporaries(run_dir: Path) -> list[Path]:
    return [p for p in run_dir.rglob("*.tmp")]


def _verified_cells(run_dir: Path) -> int:
    import json

    h = json.loads((run_dir / "provenance.json").read_text())["config_hash"]
    return len(store_mod.ResultStore(run_dir / "cells", h).finished())


# ------------------------------------------------------------------------------ mcsweep (F90 sweep)
@pytest.mark.slow
def test_disk_full_in_a_sweep_one_line_exit_1_then_same_command_resumes(monkeypatch, capsys, tmp_path, reference):
    run = tmp_path / "run"
    args = [f"hydra.run.dir={run}", *SMALL, "execution.n_jobs=1"]
    with monkeypatch.context() as m:
        _fail_store_write(m, after=4, exc=DISK_FULL)
        code, lines = _mcsweep(m, capsys, args)
    assert code == 1
    assert len(lines) == 1, lines
    failed = re.escape(str(run / "cells")) + r"/cell_[^ ;]+\.parquet"
    assert re.fullmatch(rf"mcsweep: error: no space left on device writing {failed}; 4 of {N_CELLS} cells kept in "
                        rf"{re.escape(str(run))}; free space, then {RESUME}", lines[0]), lines[0]
    assert _temporaries(run) == [] and _verified_cells(run) == 4
    log = "".join(p.read_text() for p in run.glob("*.log"))
    assert "Traceback" in log and "No space left on device" in log  # the terminal's line, the log's trace

    code, lines = _mcsweep(monkeypatch, capsys, args)
    assert code == 0, lines
    pd.testing.assert_frame_equal(_sorted(run / "cells.parquet"), _sorted(reference / "cells.parquet"),
                                  check_exact=True)


def _ignores_sigint(pid: str) -> bool:
    ignored = next(ln for ln in Path(f"/proc/{pid}/status").read_text().splitlines() if ln.startswith("SigIgn:"))
    return bool(int(ignored.split()[1], 16) >> (signal.SIGINT - 1) & 1)


def _group_alive(pgid: int) -> list[str]:
    """Processes of process group ``pgid`` that still run (zombies are dead, awaiting their reaper)."""
    alive = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        fields = text[text.rindex(")") + 2:].split()  # after "pid (comm) "
        if int(fields[2]) == pgid and fields[0] != "Z":
            alive.append(text[: text.rindex(")") + 1])
    return alive


def _wait_for_cells(proc, run: Path, n: int) -> None:
    """Until the running ``proc`` has written ``n`` cells of ``run`` (5 min at most)."""
    deadline = time.monotonic() + 300
    while len(list((run / "cells").glob("cell_*.parquet"))) < n:
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()[1][-3000:]
        time.sleep(0.02)


@pytest.mark.slow
def test_sigint_with_a_dask_cluster_one_line_no_worker_traceback(tmp_path):
    # The Dask workers run asyncio, which turns SIGINT into a traceback per worker unless
    # they start with SIGINT ignored (mcsweep.runtime.execution): the same one line as loky.
    pytest.importorskip("distributed", reason="execution=dask needs the dask extra")
    run = tmp_path / "run"
    cmd = [str(BIN / "mcsweep"), f"hydra.run.dir={run}", *SMALL, "execution=dask", "execution.n_jobs=2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _wait_for_cells(proc, run, 2)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: the app, the cluster's nannies and workers
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err[-3000:]
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and re.fullmatch(rf"mcsweep: interrupted: \d+ of {N_CELLS} cells kept in .*; {RESUME}",
                                            lines[0]), lines
    assert _temporaries(run) == []
    deadline = time.monotonic() + 60
    while (left := _group_alive(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert left == []


@pytest.mark.slow
def test_sigint_to_the_process_group_one_line_exit_130_no_worker_left_then_resumes(tmp_path, reference):
    run = tmp_path / "run"
    cmd = [str(BIN / "mcsweep"), f"hydra.run.dir={run}", *SMALL, "execution.n_jobs=2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _wait_for_cells(proc, run, 2)
        workers = [pid for pid in subprocess.run(["pgrep", "-P", str(proc.pid), "-f", "popen_loky_posix"],
                                                 capture_output=True, text=True).stdout.split()]
        assert len(workers) == 2 and all(_ignores_sigint(pid) for pid in workers)  # only the app acts on Ctrl-C
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: the app and its loky workers
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err[-3000:]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-3000:]
    lines = [ln for ln in err.splitlines() if ln.strip()]
    m = re.fullmatch(rf"mcsweep: interrupted: (\d+) of {N_CELLS} cells kept in {re.escape(str(run))}; {RESUME}",
                     lines[-1])
    assert m and len(lines) == 1, lines
    assert 2 <= int(m.group(1)) < N_CELLS and int(m.group(1)) == _verified_cells(run)
    assert _temporaries(run) == []
    deadline = time.monotonic() + 60
    while (left := _group_alive(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.1)  # loky's resource trackers exit once they see the app's end
    assert left == []

    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    pd.testing.assert_frame_equal(_sorted(run / "cells.parquet"), _sorted(reference / "cells.parquet"),
                                  check_exact=True)


# ------------------------------------------------------------------ mcsweep experiment=secondary / primary
def _catalogue(path: Path, n: int = 6000, seed: int = 3) -> Path:
    """A whole-sky catalogue, so a run does not spend its time in the galaxy model."""
    rng = np.random.default_rng(seed)
    ra = rng.uniform(0.0, 360.0, n)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    pd.DataFrame({"ra": ra, "dec": dec, "parallax": rng.uniform(0.1, 5.0, n), "pmra": rng.normal(0.0, 10.0, n),
                  "pmdec": rng.normal(0.0, 10.0, n), "phot_g_mean_mag": rng.uniform(10.5, 20.5, n)}
                 ).to_csv(path, index=False)
    return path


SECONDARY = ["experiment=secondary", "experiment.secondary.class_size=300", "execution.chunk_stars=100"]
PRIMARY = ["experiment=primary", "experiment.primary.class_size=100", "experiment.primary.extra_sources=600",
           "experiment.primary.mission_years=0.25", "experiment.primary.knot_interval_hours=24",
           "experiment.primary.attitude_timescale_hours=192", "experiment.primary.priors=[F90,10F90]"]


@pytest.mark.slow
@pytest.mark.parametrize("experiment,exc,expected", [
    (SECONDARY, DISK_FULL, r"mcsweep: error: no space left on device writing {run}/secondary_chunks/class1100_"
                           r"stars000000000-000000300\.parquet; 0 solved chunks of stars kept in {run}; free space, "
                           r"then {resume}"),
    (SECONDARY, KeyboardInterrupt(), r"mcsweep: interrupted: 1 solved chunk of stars kept in {run}; {resume}"),
    (PRIMARY, KeyboardInterrupt(), r"mcsweep: interrupted: the solutions of 1 of 2 priors \(F90\) kept in {run} "
                                   r"\(the stars and their transits are recomputed\); {resume}"),
], ids=["secondary-disk-full", "secondary-interrupt", "primary-interrupt"])
def test_global_experiments_say_what_is_kept(monkeypatch, capsys, tmp_path, experiment, exc, expected):
    run = tmp_path / "run"
    cat = _catalogue(tmp_path / "stars.csv")
    args = [f"hydra.run.dir={run}", *experiment, "population=catalogue", f"population.path={cat}",
            "execution.n_jobs=1", "execution.progress=false"]
    after = 1 if exc is not DISK_FULL else 0
    with monkeypatch.context() as m:
        _fail_store_write(m, after=after, exc=exc)
        code, lines = _mcsweep(m, capsys, args)
    assert code == (1 if exc is DISK_FULL else 130), lines
    expected = expected.format(run=re.escape(str(run)), resume=RESUME)
    assert re.fullmatch(expected, lines[-1]), lines[-1]
    assert not any("Traceback" in ln for ln in lines), lines
    assert _temporaries(run) == []


# ------------------------------------------------------------------------------ mcsweep-report
@pytest.mark.parametrize("exc,code,start", [(DISK_FULL, 1, "mcsweep-report: error: no space left on device "
                                                           "writing {run}/figures/"),
                                            (KeyboardInterrupt(), 130, "mcsweep-report: interrupted: ")])
@pytest.mark.parametrize("processes", [0, 2], ids=["in-line", "forked"])
def test_report_stopped_while_writing_leaves_whole_files_and_one_line(monkeypatch, capsys, tmp_path, reference,
                                                                      exc, code, start, processes):
    if processes and "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("figures are drawn in line here")
    run = tmp_path / "run"
    shutil.copytree(reference, run)
    cells = _sorted(run / "cells.parquet")
    # A forked child counts the writes from where its parent stood (none): the first figure
    # of each child fails; drawn in line, the second figure.
    after = 0 if processes else 1
    monkeypatch.setattr(drawing_mod, "drawing_processes", lambda: processes)
    _fail_store_write(monkeypatch, after=after, exc=exc, match=lambda p: p.suffix == ".png")
    assert report_cli.main([str(run)]) == code
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(start.format(run=run)), lines
    assert lines[0].endswith("the run's computed results in " + str(run) + " are untouched and every file the "
                             "report writes is whole (the old or the new one); "
                             + ("free space, then " if code == 1 else "") + "run the same command again"), lines[0]
    assert _temporaries(run) == [] and len(list((run / "figures").glob("*.png"))) == after
    pd.testing.assert_frame_equal(_sorted(run / "cells.parquet"), cells)


# ------------------------------------------------------------------------------ mcsweep-prior
EXAMPLE = ROOT / "examples" / "prior_solve"


@pytest.mark.parametrize("command,exc,after", [
    (["annotate", EXAMPLE / "sources.csv", "--out", "{d}/annotated.csv"], DISK_FULL, 0),
    (["solve", EXAMPLE / "observations.csv", "--sources", EXAMPLE / "sources.csv", "--out", "{d}/sol.csv"],
     DISK_FULL, 0),
    (["simulate", "--n", "8", "--out", "{d}/obs.csv", "--sources-out", "{d}/src.csv"], DISK_FULL, 1),
    (["simulate", "--n", "8", "--out", "{d}/obs.csv", "--sources-out", "{d}/src.csv"], KeyboardInterrupt(), 0),
], ids=["annotate-disk-full", "solve-disk-full", "simulate-disk-full-second-file", "simulate-interrupt"])
def test_prior_command_stopped_while_writing(monkeypatch, capsys, tmp_path, command, exc, after):
    real = prior_cli.atomic_write_via
    calls = []

    def write(path, writer):
        calls.append(path)
        if len(calls) <= after:
            return real(path, writer)

        def half_then_fail(tmp):
            writer(tmp)
            with open(tmp, "r+b") as f:
                f.truncate(max(1, os.path.getsize(tmp) // 2))
            raise exc

        return real(path, half_then_fail)

    monkeypatch.setattr(prior_cli, "atomic_write_via", write)
    args = [str(a).format(d=tmp_path) for a in command]
    code = prior_cli.main(args)
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    written = [str(p) for p in calls[:after]]
    kept = f"{', '.join(written)} written, nothing else" if written else "nothing written"
    if exc is DISK_FULL:
        assert code == 1
        assert lines == [f"mcsweep-prior: error: no space left on device writing {calls[after]}; {kept}; "
                         "free space, then run the same command again"]
    else:
        assert code == 130 and lines == [f"mcsweep-prior: interrupted: {kept}; run the same command again"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(Path(w).name for w in written)


# ------------------------------------------------------------------------------ the solver's forked workers
RESIDENT_SCRIPT = """
import sys, time
from mcsweep.solver.resident import forked_chunks

def first(item):
    return item[0]

try:
    with forked_chunks([(i,) for i in range(4)], 2) as run:
        print(sorted(run(first, [(i, i) for i in range(4)])), flush=True)
        time.sleep(120)  # the parent's own share of a pass: the workers wait for the next message
except KeyboardInterrupt:
    print("parent interrupted", flush=True)
"""


def test_resident_solver_workers_leave_an_interrupt_to_the_parent(tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", RESIDENT_SCRIPT], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        assert proc.stdout.readline().strip() == "[0, 1, 2, 3]"  # the pool is up and idle
        workers = [ln.split()[0] for ln in subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True,
                                                          text=True).stdout.splitlines()]
        assert len(workers) >= 2
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert out.strip() == "parent interrupted" and proc.returncode == 0
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err  # the workers printed nothing
    assert not any(Path(f"/proc/{pid}").exists() and "Z" not in Path(f"/proc/{pid}/stat").read_text().split()[2]
                   for pid in workers)


def test_disk_full_in_hydras_own_files_before_the_job_one_line_and_nothing_left(monkeypatch, capsys, tmp_path):
    import hydra.core.utils

    def full(cfg, filename, output_dir):  # Hydra's .hydra/*.yaml, written before the job starts
        (output_dir / filename).parent.mkdir(parents=True, exist_ok=True)
        (output_dir / filename).write_text("")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(hydra.core.utils, "_save_config", full)
    before = os.environ.get("HYDRA_FULL_ERROR")
    run = tmp_path / "run"
    code, lines = _mcsweep(monkeypatch, capsys, [f"hydra.run.dir={run}", "sky=single", "magnitudes=g15"])
    assert code == 1
    assert lines == [f"mcsweep: error: no space left on device; the run had not started in {run} (earlier results "
                     "there are kept); free space, then run the same command"]
    assert not run.exists()
    assert os.environ.get("HYDRA_FULL_ERROR") == before  # the command's setting does not outlive it
