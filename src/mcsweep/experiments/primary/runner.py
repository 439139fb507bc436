"""The one-year global (primary) experiment (paper Sect. 4.2, Table 3) on the global path.

The science lives in :mod:`mcsweep.experiments.primary.experiment` and the modules it names; the
path every global experiment shares (provenance, classes of stars, chunk store and resume, aggregation) in
:mod:`mcsweep.experiments.global_solution.run`. What is the primary's own: the transit search
through the executor in chunks of stars, the observations of all stars together, and
one global solution per prior, each a task whose per-star results are written
atomically to ``primary_chunks/`` (a killed run resumes at the next prior) with its
convergence history, attitude error series and summary beside them; then Table 3, the
factor search and the summaries.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import io
import json
import os
import warnings
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from ...errors import NotConvergedError
from ..global_solution.classes import POPULATION_STREAM, class_key, class_table, draw_class, sky_order
from ..global_solution.settings import spawn
from .sky import sky_partitions
from .experiment import EXTRA_KEY, FACTOR_STREAM, TAG, build_settings, stream_seed
from .transits import transits_of
from .local import prepare
from .prior_solution import solve_prior
from .cluster import prepare_on_cluster
from .reduction import TableReduction, reduce_parts
from .results import parts_of
from .factor import curves_from_reduction, factor_label, overall_factor, rows_from_reduction
from .table import SUBSET_COUNTS, table3_from_reduction, table3_markdown
from ...solver import AttitudeNotDetermined
from ...solver.calibration import CalibrationNotDetermined
from ...runtime.execution import dask_client, release_free_memory
from ...runtime.progress import SolveLines
from . import CHUNKS_DIR, TABLES
from ..global_solution.run import GlobalExperiment, GlobalRun
from ...runtime.store import atomic_write_bytes


__all__ = ["PRIMARY", "run_primary", "solution_line"]


def _prior_id(label: str) -> str:
    return "prior_" + label.replace(".", "p")


def _part_ids(label: str, n_stars: int) -> list[str]:
    """The store's cells of one solution's per-star results: one per part of
    :data:`~mcsweep.experiments.primary.results.PART_STARS` stars (the tables read them part
    by part, :mod:`mcsweep.experiments.primary.reduction`)."""
    return [f"{_prior_id(label)}.part{j:04d}" for j in range(len(parts_of(n_stars)))]


def _kept(pri, done, run_dir) -> str:
    """The priors whose solutions a rerun keeps (result and summary both written)."""
    labels = list(dict.fromkeys([*map(str, pri.priors), *map(factor_label, pri.factor_grid)]))
    kept = [lab for lab in labels if f"{_prior_id(lab)}.part0000" in done and _finished(Path(run_dir) / CHUNKS_DIR, lab,
                                                                          str(pri.solver_start))]
    which = f" ({', '.join(kept)})" if kept else ""
    return (f"the solutions of {len(kept)} of {len(labels)} priors{which} kept in {run_dir} "
            "(the stars and their transits are recomputed)")


def _finished(chunks: Path, label: str, solver_start: str) -> bool:
    """Whether the solution of ``label``, its store entry aside, is complete: its summary and,
    when the next solution starts from it (``solver_start='previous'``), its attitude
    coefficients; without them a resumed run could not start the next one as an
    uninterrupted run does, so it is solved again."""
    cid = _prior_id(label)
    return (chunks / f"{cid}.json").exists() and (solver_start != "previous"
                                                  or (chunks / f"{cid}_coefficients.npy").exists())


def _groups(pri) -> list[tuple[float, int, int]]:
    groups = [(float(g), pri.class_size, class_key(g)) for g in pri.g_classes]
    if pri.extra_sources > 0:  # optional extra attitude carriers (0: the paper's three classes only)
        groups.append((float(pri.extra_g_min), pri.extra_sources, EXTRA_KEY))
    return groups


def solution_line(label: str, extra: dict) -> str:
    """What the command prints when a prior's solution is done: iterations, convergence and the
    attitude error RMS per axis, written as the table notes write it."""
    rms = " / ".join(f"{v:.1f}" for v in extra["attitude_rms_uas"])
    sent = extra.get("dask_mib_per_iteration")
    return (f"mcsweep: primary: prior {label}: {extra['iterations']} PCG iterations, converged "
            f"{extra['converged']}, attitude error RMS {rms} uas (x / y / z)"
            + (f"; Dask: {sent[0]:.3g} MiB sent to and {sent[1]:.3g} MiB received from the workers per "
               "iteration" if sent else ""))


def few_transit_spans(cells: TableReduction) -> str:
    """The note on the <= 4 transit subset's time spans: whether its stars were seen in one
    visit or in several months apart decides their errors. From the solutions' cells (the
    subset as the table counts it, of the stars with live transits)."""
    parts = []
    for g in cells.g_classes:
        got = cells.span_summary(g)
        if got is not None:
            (q10, q50, q90), within = got
            parts.append(f"G~{g:g}: {q50:.3g} d [{q10:.3g}-{q90:.3g}], {within:.0%} within a day")
    return ("Time span of the live transits of the <= 4 transit stars, median [10-90 %]: " + "; ".join(parts)
            + ".") if parts else ""


def knot_rule(pri) -> str:
    """How the knot interval was chosen, as the notes of Table 3 say it."""
    if pri.knot_transits is None:
        return f"at most knot_interval_hours = {pri.knot_interval_hours:g} h"
    if pri.knot_rule == "uniform":
        return (f"knot_transits = {pri.knot_transits:g}, knot_rule = uniform: knots at the mean interval of "
                f"{pri.knot_transits:g} FoV transits, longer where fewer fall")
    return f"knot_transits = {pri.knot_transits:g} FoV transits per knot"


def _fewer_knots(pri) -> str:
    """What to set when the knots are too many for the data (the setting actually in use)."""
    if pri.knot_transits is None:
        return (f"a longer experiment.primary.knot_interval_hours than {pri.knot_interval_hours:g}, or "
                "experiment.primary.knot_transits (the paper's attitude freedom: 25)")
    return f"a larger experiment.primary.knot_transits than {pri.knot_transits:g} (fewer, longer knots)"


def _transits(run: GlobalRun, stars: pd.DataFrame) -> dict:
    """FoV transits of every star, searched in chunks through the executor, in star order."""
    chunk = int(run.config.execution.chunk_stars)
    ra, dec, s = stars["ra"].to_numpy(), stars["dec"].to_numpy(), run.settings
    jobs = [(i, lo, ra[lo:lo + chunk], dec[lo:lo + chunk], s.start_jd, s.end_jd, s.law)
            for i, lo in enumerate(range(0, len(stars), chunk))]
    # release_workers: the transit search's processes would idle, holding their memory,
    # through the solutions, which fork workers of their own.
    found = dict(run.map("transits", transits_of, jobs, release_workers=True))
    return {k: np.concatenate([found[i][k] for i in range(len(jobs))]) for k in ("star", "t", "psi", "following")}


@dataclasses.dataclass
class _Computed:
    """What the tables need besides the solutions in the store."""

    data: object        # experiments.primary.data.PreparedData (held here or on the cluster)
    factors: dict       # factor k -> its prior label (experiment.primary.factor_grid)


def _solve(run: GlobalRun, data, label: str, client: Callable, start: tuple | None) -> tuple:
    """The solution of prior ``label`` and its side files, unless finished (resume);
    ``client()``: the Dask client (``execution.backend=dask``), opened at its first call.
    ``start``: (label, file) of the solution whose attitude this one starts from
    (``experiment.primary.solver_start='previous'``), or None (from zero). Returns this
    solution's (label, file) for the next one."""
    config, settings = run.config, run.settings
    cid = _prior_id(label)
    coefficients = run.chunks / f"{cid}_coefficients.npy"
    if run.pending(_part_ids(label, data.n_stars)) or not _finished(run.chunks, label, settings.solver_start):
        # On a Dask cluster the solver's chunks are sent to the workers once per solution and
        # kept there; every pass sends only the star and attitude vectors
        # (mcsweep.solver.dask_resident; one client for every solution, opened when the first
        # one is needed). On this machine the n_jobs workers are forked per solution and keep
        # their share of the blocks (mcsweep.solver.resident). A map-like executor would
        # re-send every chunk's measurements per pass, which costs more than the work
        # (mcsweep.solver.solve.solve_global). Results are the same bits either way.
        # A line a minute while it runs: at the paper's sizes with AGIS's knots one solution
        # takes up to an hour (docs/notes/table3/candidates_paper_sizes.md), with nothing else to show it is getting there.
        log = SolveLines(f"mcsweep: primary: prior {label}", lambda r: settings.describe_state(dataclasses.asdict(r)),
                         f"{settings.describe_criterion()} or experiment.primary.solver_max_iter {settings.max_iter}",
                         enabled=bool(config.execution.progress))
        # The stored coefficients (bit for bit the solution's, kept as long as the solution:
        # _finished), so a resumed run starts from what an uninterrupted one would.
        a0 = None if start is None else np.load(start[1])
        try:
            if config.execution.backend == "dask":
                res, hist, extra, series, attitude = solve_prior(
                    settings, data, label, log=log, dask_client=client(), chunk_stars=int(config.execution.chunk_stars),
                    attitude_start=a0)
            else:
                workers = int(config.execution.n_jobs) if config.execution.backend in ("loky", "threading") else 1
                res, hist, extra, series, attitude = solve_prior(settings, data, label, log=log, workers=workers,
                                                                 attitude_start=a0)
        except AttitudeNotDetermined as exc:
            # The knots are closer than these stars' transits can fix under this prior: found
            # only when the prior's Schur block is factorised, after the solutions before it
            # (docs/notes/table3/prior_1000mas.md). Not a bad value as such (the same setting works for the
            # other priors and on other data), so like a solution that did not converge: one
            # line, exit status 3, no table3, and the finished solutions kept for a rerun.
            raise NotConvergedError(
                f"the {label} solution cannot start: the attitude near TCB JD "
                f"{data.spline.greville()[exc.coefficient]:.4f} (spline coefficient {exc.coefficient}, axis "
                f"{exc.axis}) is not determined by the data under this prior, {knot_rule(run.section)} "
                f"({data.transits_per_knot:.3g} FoV transits per knot on average); no table3 written, the "
                f"solutions finished before it are kept; accepted: {_fewer_knots(run.section)}") from None
        except CalibrationNotDetermined as exc:
            # The same kind of end (mcsweep.solver.calibration): some combination of the
            # variation's unknowns has no measurement.
            raise NotConvergedError(
                f"the {label} solution cannot fix experiment.primary.basic_angle_harmonics="
                f"{settings.basic_angle_harmonics}: {exc}; no table3 written, the solutions finished before it "
                "are kept; accepted: fewer harmonics, or 0 (no calibration unknowns)") from None
        atomic_write_bytes(run.chunks / f"{cid}_history.csv", hist.to_csv(index=False).encode())
        if not extra["converged"] and not settings.allow_unconverged:
            # Not a result (Table 3 would tabulate a solution PCG did not reach): only its
            # history is kept, for the diagnosis; no store entry, so no resume takes it.
            last = hist.iloc[-1] if len(hist) else None
            raise NotConvergedError(
                f"the {label} solution did not converge in {extra['iterations']} PCG iterations "
                f"({settings.describe_state(last)} against {settings.describe_criterion()}); no table3 written, the "
                f"history is in {run.chunks / f'{cid}_history.csv'}; raise experiment.primary.solver_max_iter or set "
                "experiment.primary.allow_unconverged=true to tabulate it marked" if last is not None else
                f"the {label} solution did not start (no PCG iteration); no table3 written")
        extra["attitude_start"] = "zero" if start is None else start[0]
        atomic_write_bytes(run.chunks / f"{cid}_attitude.csv", series.to_csv(index=False).encode())
        buf = io.BytesIO()
        np.save(buf, attitude)
        atomic_write_bytes(coefficients, buf.getvalue())
        atomic_write_bytes(run.chunks / f"{cid}.json", json.dumps(extra).encode())
        # one part in memory at a time (on a cluster each gathered from the workers holding its stars)
        for part, df in zip(_part_ids(label, res.n_stars), res.parts(), strict=True):
            run.store.write(part, df)
        del res
        release_free_memory()  # the solution's temporaries, before the next one
        print(solution_line(label, extra), flush=True)
    return (label, coefficients) if settings.solver_start == "previous" else None


def _compute(run: GlobalRun) -> _Computed:
    factors = {float(k): factor_label(k) for k in run.section.factor_grid}
    with contextlib.ExitStack() as cluster:
        client = functools.cache(lambda: cluster.enter_context(dask_client(run.config.execution)))
        if run.config.execution.backend == "dask":
            data = _observations_on_cluster(run, client())
        else:
            data = _observations(run, _table(run))
        _record_attitude(run, data)
        # The factor search (experiment.primary.factor_grid) shares solutions with Table 3's priors.
        start = None  # each solution from the one before (experiment.primary.solver_start)
        for label in dict.fromkeys([*run.settings.priors, *factors.values()]):
            with run.prov.stage(f"solve {label}"):
                start = _solve(run, data, label, client, start)
    return _Computed(data=data, factors=factors)


def _table(run: GlobalRun) -> pd.DataFrame:
    """The solution's table of stars in this process: every class, in sky order."""
    parts = [class_table(df, key) for _, key, df in run.classes]
    # The draws (every column of the population) are not needed again: at the paper's sizes
    # they, this table and the solution's copy of it (data.stars) held 260 bytes per star.
    run.classes = []
    stars = pd.concat(parts, ignore_index=True)
    del parts
    # One solution holds every class: its blocks of consecutive stars are then regions of the sky
    # (mcsweep.experiments.global_solution.classes, "Sky order"), whatever the classes' own order.
    return stars.iloc[sky_order(stars["ra"].to_numpy(), stars["dec"].to_numpy())].reset_index(drop=True)


def _observations(run: GlobalRun, stars: pd.DataFrame):
    """The data of every prior's solution, made in this process."""
    transits = _transits(run, stars)
    print(f"mcsweep: primary: {len(stars)} stars, {transits['t'].size} FoV transits found", flush=True)
    with run.prov.stage("observations"):
        data = prepare(run.settings, stars, transits)
        del transits, stars  # 16 bytes per transit, 2.6e7 transits at the paper's scale; data.stars has the table
        release_free_memory()  # the blocks' build leaves free holes in the heap (1/3 of it at 3e5 stars)
    return data


def _observations_on_cluster(run: GlobalRun, client):
    """The data of every prior's solution made and kept on the Dask cluster's workers, down to
    the stars (:mod:`mcsweep.experiments.primary.sky`, :mod:`mcsweep.experiments.primary.cluster`):
    each class drawn by a task (the galaxy model built there, or the catalogue read there: its
    path must be readable by the workers, as on a cluster's shared file system), put in sky
    order there; only numbers per partition, block and chunk come back to this process."""
    settings, pri = run.settings, run.section
    population = dataclasses.asdict(run.config.population)
    if population.get("path"):  # a catalogue, read where the workers run: its path as this process sees it
        population["path"] = os.path.abspath(population["path"])
    chunk = int(run.config.execution.chunk_stars)
    with run.prov.stage("population"):
        # (a class is drawn again only if a lost worker took a partition of the sky)
        classes = [(key, functools.partial(client.submit, draw_class, (population, float(g), n, key, spawn(
            settings.seed, TAG, POPULATION_STREAM, key), "experiment.primary.class_size"), pure=False))
                   for g, n, key in _groups(pri)]
        sky, caught = sky_partitions(client, classes, chunk)
        del classes
    for category, message in caught:  # the workers' warnings, where the user sees them
        warnings.warn(message, category, stacklevel=2)
    with run.prov.stage("observations"):
        data = prepare_on_cluster(settings, sky, client, chunk_stars=chunk)
    print(f"mcsweep: primary: {data.n_stars} stars, {data.n_fov_transits} live FoV transits of the solved "
          f"stars, built on the Dask workers", flush=True)
    return data


def _record_attitude(run: GlobalRun, data) -> None:
    with run.prov.stage("observations"):
        run.prov.derived.setdefault("primary", {}).update(
            {"attitude_segments": data.spline.n_segments, "knot_interval_hours": data.mean_knot_interval_hours,
             "fov_transits_per_knot": data.transits_per_knot, "attitude_coefficients": 3 * data.spline.n_coef,
             "attitude_coefficients_without_data": 3 * (data.spline.n_coef - data.coefficients_with_data())})


def _read_solutions(run: GlobalRun, factors: dict) -> tuple[list, dict, list]:
    """Per prior: the convergence history, summary and attitude errors (the per-star results
    are read part by part by :func:`_cells`)."""
    histories, extras, attitude = [], {}, []
    for label in dict.fromkeys([*run.settings.priors, *factors.values()]):
        cid = _prior_id(label)
        histories.append(pd.read_csv(run.chunks / f"{cid}_history.csv"))
        att_file = run.chunks / f"{cid}_attitude.csv"
        if att_file.exists():  # absent only in a resumed run of an older version
            attitude.append(pd.read_csv(att_file).assign(prior=label))
        extras[label] = json.loads((run.chunks / f"{cid}.json").read_text())
    return histories, extras, attitude


def _cells(run: GlobalRun, factors: dict, n_stars: int) -> TableReduction:
    """Table 3's and the factor search's cells of every solution, read from the store part
    by part (:mod:`mcsweep.experiments.primary.reduction`): never a whole solution in memory."""
    pri = run.section
    labels = list(dict.fromkeys([*run.settings.priors, *factors.values()]))
    ids = {label: _part_ids(label, n_stars) for label in labels}

    def read(j: int) -> dict:
        return dict(zip(labels, run.read_all([ids[label][j] for label in labels])))

    return reduce_parts(read, len(parts_of(n_stars)), TableReduction(
        labels, pri.g_classes, run.settings.confidence, count=SUBSET_COUNTS[pri.subset_transits], factors=factors,
        ranked=run.settings.priors))


def _aggregate(run: GlobalRun, computed: _Computed) -> dict[str, str]:
    pri, settings, data, factors = run.section, run.settings, computed.data, computed.factors
    histories, extras, attitude = _read_solutions(run, factors)
    cells = _cells(run, factors, data.n_stars)
    table = table3_from_reduction(cells, settings.priors, converged={k: extras[k]["converged"] for k in settings.priors})
    outputs = {}
    if factors:
        rng = np.random.default_rng(stream_seed(settings.seed, FACTOR_STREAM))
        fac = rows_from_reduction(cells, n_resamples=pri.factor_resamples, rng=rng)
        k_all, flag = overall_factor(fac)
        fac = pd.concat([fac, pd.DataFrame([{"subset": "all", "g_class": "all", "k_min": k_all, "flag": flag}])],
                        ignore_index=True)
        outputs["primary_factor.csv"] = fac.to_csv(index=False)
        outputs["primary_factor_curves.csv"] = curves_from_reduction(cells).to_csv(index=False)
    n_obs = data.n_measurements
    summary = pd.DataFrame([{"prior": k, **{kk: (json.dumps(v) if isinstance(v, list) else v)
                                            for kk, v in e.items()}} for k, e in extras.items()])
    summary["n_stars_solved"] = data.n_solved
    summary["n_measurements"] = n_obs
    summary["n_attitude_coefficients"] = 3 * data.spline.n_coef
    summary["knot_interval_hours"] = data.mean_knot_interval_hours  # realised mean over the live time
    summary["fov_transits_per_knot"] = data.transits_per_knot
    summary["attitude_segments"] = data.spline.n_segments
    summary["dead_fraction"] = data.dead_days / (settings.end_jd - settings.start_jd)
    counts = cells.class_counts
    notes = [run.conditions(f"{pri.mission_years:g} year(s) from {pri.mission_start} (TCB), dead time "
                            f"{100 * pri.dead_time_fraction:g} % in outages of {pri.dead_time_outage_days:g} d"),
             f"Stars: {pri.class_size} per class (paper 5e5), {counts.get(EXTRA_KEY, 0)} extra stars "
             f"(G >= {pri.extra_g_min:g}); {data.n_solved} with >= 1 transit, {n_obs} measurements; "
             f"attitude: cubic spline in {data.spline.n_segments} segments between the dead-time gaps, "
             f"knot interval {data.mean_knot_interval_hours:.3g} h ({knot_rule(pri)}), "
             f"{data.transits_per_knot:.1f} FoV transits per knot, {3 * data.spline.n_coef} coefficients; "
             f"true attitude = law + {pri.attitude_amplitude_mas:g} mas "
             f"random spline rotation on a {pri.attitude_timescale_hours:g} h time scale."
             + (" Positions evaluated at each star's own mean epoch of its live transits "
                "(experiment.primary.evaluation_epoch=star_mean)." if settings.evaluation_epoch == "star_mean" else "")
             + (" The <= 4 / > 4 subsets count the FoV transits the scanning law scheduled, before the dead "
                "time (experiment.primary.subset_transits=scheduled)." if pri.subset_transits == "scheduled" else ""),
             *filter(None, [few_transit_spans(cells), calibration_note(pri, extras)]),
             "PCG iterations / attitude error RMS (x, y, z) [uas] after the frame correction: "
             + "; ".join(f"{k}: {e['iterations']} ({'converged' if e['converged'] else 'NOT converged'}"
                         + _started(e) + "), "
                         + ", ".join(f"{v:.2f}" for v in e["attitude_rms_uas"]) for k, e in extras.items())
             + "."]
    outputs.update({"table3.csv": table.to_csv(index=False),
                    "table3.md": table3_markdown(table, settings.confidence, notes),
                    "primary_convergence.csv": pd.concat(histories, ignore_index=True).to_csv(index=False),
                    "primary_summary.csv": summary.to_csv(index=False)})
    outputs["primary_attitude_segments.csv"] = data.spline.segments_frame().to_csv(index=False)
    if attitude:
        outputs["primary_attitude_error.csv"] = pd.concat(attitude, ignore_index=True).to_csv(index=False)
    return outputs


def _started(extra: dict) -> str:
    """Where a solution's PCG started (experiment.primary.solver_start), for the table notes."""
    start = extra.get("attitude_start", "zero")
    return "" if start == "zero" else f", from the {start} attitude"


def calibration_note(pri, extras: dict) -> str | None:
    """The calibration solved with the stars and attitude, per prior: a basic-angle variation
    (``basic_angle_harmonics``; Sect. 5 of the paper names geometric calibration parameters as
    part of a primary solution)."""
    if not pri.basic_angle_harmonics:
        return None
    per = "; ".join(f"{k}: " + ", ".join(f"{n} {1e3 * v:.2f}" for n, v in e.get("basic_angle_mas", {}).items())
                    for k, e in extras.items())
    return (f"Calibration: a basic-angle variation with {pri.basic_angle_harmonics} harmonic(s) of the spin phase "
            f"solved with the stars and the attitude, its unknowns bordering the normal equations of one PCG "
            f"(experiment.primary.basic_angle_harmonics; its cos Omega term is degenerate with a shift of every "
            f"parallax, Butkevich et al. 2017). Fitted [uas]: {per}.")


#: The primary experiment on the global path (:func:`~mcsweep.experiments.global_solution.run.run_global`).
PRIMARY = GlobalExperiment(
    kind="primary", tag=TAG, chunks_dir=CHUNKS_DIR, build_settings=build_settings, groups=_groups,
    compute=_compute, aggregate=_aggregate, tables=TABLES, kept=_kept,
    draws_on_workers=lambda config: config.execution.backend == "dask",
    seeds={"population": "SeedSequence(seed, spawn_key=(42, 0, round(100*G0) or 0 for the extra stars))",
           "dead_time": "SeedSequence(seed, spawn_key=(42, 1))",
           "true_attitude": "SeedSequence(seed, spawn_key=(42, 2))",
           "noise": "SeedSequence(seed, spawn_key=(42, 3))",
           "factor_bootstrap": "SeedSequence(seed, spawn_key=(42, 4))"})
