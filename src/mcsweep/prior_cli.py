"""The ``mcsweep-prior`` command: apply the prior to a user's catalogue or observations.

``mcsweep-prior annotate CATALOGUE --out OUT [--run RUN_DIR | --paper]`` adds
``sigma_f90_parallax`` [mas] and ``sigma_f90_pm`` [mas/yr] to a catalogue
(:mod:`mcsweep.prior.annotate`).

``mcsweep-prior solve OBSERVATIONS --out OUT [--sources SOURCES] [--run RUN_DIR | --paper]
[--factor K] [--confidence P]`` solves each source's few FoV transits with the prior
(:mod:`mcsweep.prior.observations`).

``mcsweep-prior simulate --out OBS --sources-out SOURCES`` writes an example input with
the project's simulator (:mod:`mcsweep.prior.example`).

The prior is the paper's (``--paper``, the default) or a sweep's fit (``--run``). Bad
input ends with one line on stderr and exit status 2, and nothing is written: the
output goes to a temporary name in the destination directory and is moved into place
(atomically, with the mode ``0666 & ~umask`` of a normally created file) only when
complete. The command sits after every stage (like ``mcsweep``), so it may use the
sweep's file conventions. Ctrl-C and a full disk end it with one line naming what was
written, exit status 130 or 1 (:mod:`mcsweep.runtime.interruption`); the unfinished
output's temporary file is removed.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .errors import UserInputError, report_user_error
from .prior import Prior
from .prior.annotate import detect_format
from .runtime.interruption import exit_on_second_interrupt, is_disk_full, report_stop
from .runtime.store import atomic_write_via

__all__ = ["main"]

PROG = "mcsweep-prior"


def _prior(args) -> Prior:
    bright = args.bright
    return Prior.from_run(args.run, bright=bright) if args.run else Prior.paper(bright=bright)


#: Outputs moved into place by this command so far (what a stopped command still leaves).
_published: list[Path] = []


def _publish(out: Path, write) -> None:
    """Call ``write(tmp_path)`` and move the finished file to ``out``; no file is left on error."""
    out = Path(out)
    if not out.parent.is_dir():
        raise UserInputError(f"--out {out}: directory {out.parent} does not exist; expected an existing directory")
    if out.is_dir():
        raise UserInputError(f"--out {out} is a directory; expected a file name")
    atomic_write_via(out, write)
    _published.append(out)


def _stopped(exc: BaseException) -> int:
    exit_on_second_interrupt()
    done = f"{', '.join(map(str, _published))} written, nothing else" if _published else "nothing written"
    return report_stop(PROG, exc, done, "run the same command again")


def _annotate(args) -> str:
    from .prior.annotate import annotate_file

    prior = _prior(args)
    fmt_out = detect_format(args.out)
    t0 = time.perf_counter()
    n = [0]

    if args.old_mean_columns:
        print(f"{PROG}: --old-mean-columns is deprecated: the prior's centre is named prior_mean_parallax_mas, "
              "prior_mean_pmra_mas_yr and prior_mean_pmdec_mas_yr, as in the tables of solve", file=sys.stderr)

    def write(tmp):
        n[0] = annotate_file(args.catalogue, tmp, prior, out_format=fmt_out, old_mean_columns=args.old_mean_columns)

    _publish(args.out, write)
    dt = time.perf_counter() - t0
    return f"{n[0]} rows annotated with the {prior.origin} prior in {dt:.2f} s -> {args.out}"


def _execution(args):
    """The execution backend's settings for ``--jobs`` / ``--dask`` (:mod:`mcsweep.runtime.execution`)."""
    from types import SimpleNamespace

    if args.jobs < 1:
        raise UserInputError(f"--jobs {args.jobs} is not accepted; expected a positive number of processes")
    if args.dask is not None:
        return SimpleNamespace(backend="dask", n_jobs=args.jobs,
                               scheduler_address=None if args.dask == "local" else args.dask)
    return SimpleNamespace(backend="loky" if args.jobs > 1 else "sequential", n_jobs=args.jobs,
                           scheduler_address=None)


def _solve(args) -> str:
    from .prior.epoch_solve import looks_like_epoch_astrometry

    if looks_like_epoch_astrometry(args.observations):
        return _solve_epochs(args)
    from .prior.observations import read_observations, solve_observations, write_solutions

    if args.model is not None:
        raise UserInputError(f"--model {args.model} is not accepted for {args.observations.name}; expected it only "
                             "with Gaia epoch astrometry (one row per transit with per-CCD arrays)")
    prior = _prior(args)
    fmt_out = detect_format(args.out)
    t0 = time.perf_counter()
    obs = read_observations(args.observations, args.sources)
    sol = solve_observations(obs, prior, factor=args.factor, confidence=args.confidence,
                             reference_epoch=args.reference_epoch or "star_mean")
    _publish(args.out, lambda tmp: write_solutions(sol, tmp, fmt_out))
    dt = time.perf_counter() - t0
    return f"{len(sol)} sources solved with the {prior.origin} prior in {dt:.2f} s -> {args.out}"


def _solve_epochs(args) -> str:
    from .prior.epoch_solve import solve_epoch_file
    from .prior.observations import TableWriter
    from .runtime.execution import executor

    prior = _prior(args)
    conf = _execution(args)
    fmt_out = detect_format(args.out)
    t0 = time.perf_counter()
    n = [0]

    def write(tmp):
        with executor(conf) as run, TableWriter(tmp, fmt_out) as out:
            for table in solve_epoch_file(args.observations, args.sources, prior, model=args.model or "5p",
                                          factor=args.factor, confidence=args.confidence,
                                          reference_epoch=args.reference_epoch or "J2017.5",
                                          run=None if conf.backend == "sequential" else run,
                                          n_workers=conf.n_jobs):
                out.write(table)
                n[0] += len(table)

    _publish(args.out, write)
    dt = time.perf_counter() - t0
    return (f"{n[0]} sources of Gaia epoch astrometry solved ({args.model or '5p'}) with the {prior.origin} prior "
            f"in {dt:.2f} s -> {args.out}")


def _simulate(args) -> str:
    from .prior.example import simulate_example
    from .prior.observations import write_solutions

    if args.n < 1:
        raise UserInputError(f"--n {args.n} is not accepted; expected a positive number of sources")
    obs, src = simulate_example(args.n, seed=args.seed)
    for table, out in ((obs, args.out), (src, args.sources_out)):
        fmt = detect_format(out)
        _publish(out, lambda tmp, t=table, f=fmt: write_solutions(t, tmp, f))
    return f"{len(obs)} transits of {len(src)} sources -> {args.out}, {args.sources_out}"


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog=PROG, description="Apply the parallax prior of Michalik et al. (2015) "
                                 "to your own catalogue or observations.")
    sub = ap.add_subparsers(dest="command", required=True)

    def prior_options(p):
        g = p.add_mutually_exclusive_group()
        g.add_argument("--run", type=Path, help="use the prior fitted by this mcsweep run directory")
        g.add_argument("--paper", action="store_true", help="use the paper's Eqs. 14-17 (default)")
        p.add_argument("--bright", choices=("extrapolate", "clamp"), default="extrapolate",
                       help="stars brighter than the fit range: extrapolate the polynomials (default) or clamp")
        p.add_argument("--out", type=Path, required=True, help="output file (format from its suffix)")

    a = sub.add_parser("annotate", help="add sigma_f90_parallax [mas] and sigma_f90_pm [mas/yr] to a catalogue")
    a.add_argument("catalogue", type=Path, help="FITS, VOTable, ECSV, CSV or Parquet file with Gaia column names")
    prior_options(a)
    a.add_argument("--old-mean-columns", action="store_true",
                   help="deprecated: name a mean-centred prior's centre prior_mean_parallax, prior_mean_pmra and "
                        "prior_mean_pmdec, as before (now prior_mean_parallax_mas, prior_mean_pmra_mas_yr, "
                        "prior_mean_pmdec_mas_yr)")
    a.set_defaults(run_command=_annotate)

    s = sub.add_parser("solve", help="solve your own FoV transits of a few sources with the prior")
    s.add_argument("observations", type=Path, help="one row per FoV transit: our columns (README: 'Using the "
                   "prior') or Gaia DR4 epoch astrometry (archive or DPAC files)")
    s.add_argument("--sources", type=Path, help="sources table (source_id, ra, dec, phot_g_mean_mag) if not "
                   "in the observations")
    prior_options(s)
    s.add_argument("--factor", type=float, default=1.0, help="use K x sigma_F90 as the prior (default 1)")
    s.add_argument("--confidence", type=float, default=None, help="P of the confidence ellipse "
                   "(default: the prior's, 0.9 for the paper)")
    s.add_argument("--reference-epoch", default=None,
                   help="'star_mean' (each source's mean transit epoch; the default for per-transit input), "
                   "a Julian year 'J2017.5' or '2017.5' (the default for Gaia epoch astrometry) or an ISO date, TCB")
    s.add_argument("--model", default=None,
                   help="Gaia epoch astrometry: '5p' (default) or '6p' (DR4's, with the pseudo-colour constrained)")
    s.add_argument("--jobs", type=int, default=1, help="Gaia epoch astrometry: local processes (default 1)")
    s.add_argument("--dask", nargs="?", const="local", default=None, metavar="ADDRESS",
                   help="Gaia epoch astrometry: solve on a Dask cluster (a new local one, or the scheduler at "
                   "ADDRESS); needs pip install 'mcsweep[dask]'")
    s.set_defaults(run_command=_solve)

    e = sub.add_parser("simulate", help="write an example observations and sources table (the project's simulator)")
    e.add_argument("--out", type=Path, required=True, help="observations file (one row per FoV transit)")
    e.add_argument("--sources-out", type=Path, required=True, help="sources file (with the true parameters)")
    e.add_argument("--n", type=int, default=40, help="sources drawn (those without transits are dropped)")
    e.add_argument("--seed", type=int, default=2015)
    e.set_defaults(run_command=_simulate)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    _published.clear()
    try:
        message = args.run_command(args)
    except UserInputError as exc:
        return report_user_error(exc, prog=PROG)
    except KeyboardInterrupt as exc:
        return _stopped(exc)
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        return _stopped(exc)
    print(f"{PROG}: {message}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
