"""The ``mcsweep`` command: a Hydra app running one study per job.

``mcsweep`` with no arguments runs the full default sweep (48 HEALPix directions x
14 G bins x the prior grid) and its report; ``mcsweep experiment=secondary`` runs the
whole-sky secondary solution of Sect. 4.1. Outputs go to Hydra's run directory
(``hydra.run.dir=PATH``); ``mcsweep -m confidence=0.8,0.9,0.95`` runs one job per
value. Bad values end the command with one line on stderr and exit status 2 before
any output is written (:func:`mcsweep.command.validate.preflight`); a user error found
once the job has started (a catalogue, a run directory) removes exactly the paths this
command created and puts back what Hydra rewrote (:mod:`mcsweep.command.rundir`), never
a file or directory that was there before. Ctrl-C and a full disk end it with one line
saying how many results are kept and to rerun the same command to resume, exit status
130 or 1 (:mod:`mcsweep.runtime.interruption`); their traceback goes to the run's log only.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import os
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from .errors import EXIT_NOT_CONVERGED, NotConvergedError, UserInputError, report_user_error
from .runtime.interruption import (EXIT_INTERRUPTED, exit_on_second_interrupt, is_disk_full,
                                   remove_unfinished_writes, report_stop)
from .command.renamed import with_new_names
from .command.rundir import release, snapshot_for, undo_unstarted
from .runtime.logs import quiet_third_party_console
from .command.schema import register_configs
from .command.validate import ignored_settings, preflight, to_config

# The experiments, their runners and the report are imported by the job that needs them
# (run_job): a mistyped override ends before scipy.stats, matplotlib and astropy are loaded,
# which take seconds.

__all__ = ["main", "console_main"]

register_configs()


def refuse_foreign_outputs(run_dir: Path, outputs) -> None:
    """Refuse a run directory that already holds files named like our outputs but is no run.

    Without ``provenance.json`` nothing there was written by mcsweep, so a ``report.md``
    or a non-empty ``figures/`` is the user's own and a successful run would overwrite it.
    """
    from .command.provenance import PROVENANCE_FILE

    if (run_dir / PROVENANCE_FILE).exists():
        return
    taken = [n for n in outputs if (p := run_dir / n).is_file() or (p.is_dir() and any(p.iterdir()))]
    if taken:
        raise UserInputError(
            f"run directory {run_dir} already holds {', '.join(taken)} but is not an mcsweep run (no "
            f"{PROVENANCE_FILE}); expected a new or empty directory, or an mcsweep run to resume: "
            "choose another hydra.run.dir")


def _log_to_files(logger: logging.Logger, msg: str, exc_info) -> None:
    """Write ``msg`` and the traceback to the log files only (the terminal gets Hydra's copy)."""
    record = logger.makeRecord(logger.name, logging.ERROR, __file__, 0, msg, (), exc_info)
    # On a full disk the log cannot take it: the terminal must not get logging's own trace.
    quiet, logging.raiseExceptions = logging.raiseExceptions, False
    try:
        for h in logging.getLogger().handlers:
            if isinstance(h, logging.FileHandler):
                h.handle(record)
                with contextlib.suppress(OSError):
                    h.flush()
    finally:
        logging.raiseExceptions = quiet


def _stopped(cfg: DictConfig, run_dir: Path, exc: BaseException) -> int:
    """Ctrl-C or a full disk: the one line on the terminal, the traceback in the log; the exit status."""
    exit_on_second_interrupt()
    what = "interrupted" if isinstance(exc, KeyboardInterrupt) else "stopped: the disk is full"
    _log_to_files(logging.getLogger(__name__), f"mcsweep {what}", (type(exc), exc, exc.__traceback__))
    remove_unfinished_writes(run_dir)
    try:
        from .command.provenance import config_hash

        from .experiments.registry import get

        config = to_config(cfg)
        kept = get(config.experiment.name).kept(config, config_hash(OmegaConf.to_container(cfg, resolve=True)),
                                                run_dir)
    except Exception:  # noqa: BLE001 - the line must come out; the count is a courtesy
        kept = f"finished results kept in {run_dir}"
    return report_stop("mcsweep", exc, kept)


def _undo(run_dir: Path) -> None:
    """Remove what this command wrote for the refused job; keep everything that was there."""
    snap = snapshot_for(run_dir)
    snap.undo(run_dir)
    if snap.root != Path(os.path.abspath(run_dir)) and set(snap.new_paths()) <= {"multirun.yaml", "."}:
        snap.undo()  # a multirun stopped at its first job: its sweep directory goes too


def run_job(cfg: DictConfig, run_dir: Path) -> Path:
    """Run the job described by a composed config in ``run_dir``; returns the report path."""
    from .command.provenance import Provenance
    from .experiments.registry import get
    from .report.build import build_report

    config = to_config(cfg)
    raw = OmegaConf.to_container(cfg, resolve=True)
    experiment = get(config.experiment.name)
    prov = Provenance(run_dir, raw, kind=experiment.kind)
    refuse_foreign_outputs(run_dir, experiment.all_outputs)
    prov.check_compatible()
    experiment.run(config, raw, run_dir, prov)
    prov.write()
    with prov.stage("report"):
        report = build_report(run_dir)
    prov.write()
    return report


@hydra.main(config_path="conf", config_name="config", version_base="1.3")
def _hydra_entry(cfg: DictConfig) -> None:
    quiet_third_party_console()
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    snapshot_for(run_dir)  # taken before Hydra wrote, by RunDirGuard; else now
    try:
        report = run_job(cfg, run_dir)
    except UserInputError as exc:
        _undo(run_dir)
        sys.exit(report_user_error(exc))
    except KeyboardInterrupt as exc:
        sys.exit(_stopped(cfg, run_dir, exc))
    except NotConvergedError as exc:
        _log_to_files(logging.getLogger(__name__), "mcsweep stopped: a solution did not converge", sys.exc_info())
        print(f"mcsweep: error: {exc}", file=sys.stderr)
        sys.exit(EXIT_NOT_CONVERGED)
    except Exception as exc:
        if is_disk_full(exc):
            sys.exit(_stopped(cfg, run_dir, exc))
        # A bug, not a user error: the outputs stay (a rerun resumes), the traceback is
        # printed by Hydra (exit status 1) and kept in the run's log for the bug report.
        _log_to_files(logging.getLogger(__name__), "mcsweep stopped on an unexpected error", sys.exc_info())
        raise
    finally:
        release(run_dir)
    print(f"mcsweep: results in {run_dir} (report: {report})", file=sys.stderr)


def console_main() -> None:
    """The ``mcsweep`` command: :func:`main`, then the process ends."""
    main()
    # The run is written and closed. At exit the interpreter would run a full garbage
    # collection over every object the run left (0.6 s after a sweep); frozen objects are
    # skipped, and the operating system takes their memory back. Module teardown, atexit
    # handlers and the flushing of files and logs still run. (Not in main: a process that
    # calls it and goes on, a test's, would keep those objects for good.)
    gc.freeze()


def main() -> None:
    # Hydra prints any exception escaping its own code (its .hydra/*.yaml on a full disk)
    # as a traceback and exits 1; with this it is raised instead, so a full disk gets its
    # one line here and a bug still ends with its (whole) traceback and status 1.
    full_error = os.environ.get("HYDRA_FULL_ERROR")
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        sys.argv[1:], renamed = with_new_names(sys.argv[1:])  # Hydra reads sys.argv
        for line in renamed:
            print(f"mcsweep: warning: {line}", file=sys.stderr)
        try:
            configs = preflight(sys.argv[1:])
        except UserInputError as exc:
            sys.exit(report_user_error(exc))
        for line in ignored_settings(sys.argv[1:], configs):
            print(f"mcsweep: warning: {line}", file=sys.stderr)
        _hydra_entry()
    except KeyboardInterrupt:
        # Before a job started (or between the jobs of a multirun): no result of it exists yet.
        print("mcsweep: interrupted before a run started; run the same command to start it", file=sys.stderr)
        sys.exit(EXIT_INTERRUPTED)
    except Exception as exc:
        if not is_disk_full(exc):
            raise
        # Only Hydra's own writes get here (the job handles its own): nothing of a run yet.
        where = ", ".join(map(str, undo_unstarted())) or "its directory"
        sys.exit(report_stop("mcsweep", exc, f"the run had not started in {where} (earlier results there are kept)",
                             "run the same command"))
    finally:
        if full_error is None:
            os.environ.pop("HYDRA_FULL_ERROR", None)
        else:
            os.environ["HYDRA_FULL_ERROR"] = full_error
