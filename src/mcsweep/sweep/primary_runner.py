"""Run the one-year global (primary) experiment (paper Sect. 4.2, Table 3).

The science lives in :mod:`mcsweep.experiments.primary`; this module schedules it: the
transit search goes through the configured executor in chunks of stars; the global
solution of each prior is one task whose per-star results are written atomically to
``primary_chunks/`` (a killed run resumes at the next prior); the tables are written at
the end.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
from pathlib import Path

import numpy as np
import pandas as pd

from ..experiments.epoch import describe_reference_epoch
from ..experiments.primary import (CHUNKS_DIR, FACTOR_STREAM, POPULATION_STREAM, PRIMARY_KEY, STAR_COLUMNS,
                                   build_settings, prepare, solve_prior, stream_seed, transits_of)
from ..experiments.primary_factor import factor_curves, factor_label, factor_rows, overall_factor
from ..experiments.primary_table import table3_markdown, table3_rows
from ..experiments.secondary import class_key, select_class_stars
from ..population import make_source
from .execution import executor, release_free_memory
from .provenance import Provenance
from .store import CellStore, atomic_write_bytes

__all__ = ["run_primary"]

log = logging.getLogger(__name__)


def _prior_id(label: str) -> str:
    return "prior_" + label.replace(".", "p")


def run_primary(config, raw_cfg: dict, run_dir, *, prov=None) -> Path:
    """Run (or resume) the experiment in ``run_dir``; returns the path of ``table3.csv``."""
    run_dir = Path(run_dir)
    prov = prov or Provenance(run_dir, raw_cfg, kind="primary")
    prov.check_compatible()
    pri = config.experiment.primary
    settings = build_settings(config)
    epoch = describe_reference_epoch(settings.reference_epoch, settings.start_jd, settings.end_jd)
    prov.derived["primary"] = {"reference_epoch": epoch}
    with prov.stage("population"):
        source = make_source(dataclasses.asdict(config.population))
        parts = []
        groups = [(float(g), pri.class_size, class_key(g)) for g in pri.g_classes]
        if pri.primary_sources > 0:  # optional extra attitude carriers (0: the paper's three classes only)
            groups.append((float(pri.primary_g_min), pri.primary_sources, PRIMARY_KEY))
        for g, n, key in groups:
            rng = np.random.default_rng(stream_seed(settings.seed, POPULATION_STREAM, key))
            df = select_class_stars(source, g, n, rng)[list(STAR_COLUMNS)]
            df["class_key"] = key
            parts.append(df)
        del source
        stars = pd.concat(parts, ignore_index=True)
    prov.write(with_manifest=False)
    store = CellStore(run_dir / CHUNKS_DIR, prov.hash, accept_other_versions=config.resume.accept_other_versions)
    store.remove_stale_temporaries()
    # release_workers: the transit search's processes would idle, holding their memory,
    # through the solutions, which fork workers of their own.
    with prov.stage("transits"), executor(config.execution, release_workers=True) as run:
        chunk = int(config.execution.chunk_stars)
        ra, dec = stars["ra"].to_numpy(), stars["dec"].to_numpy()
        jobs = [(i, lo, ra[lo:lo + chunk], dec[lo:lo + chunk], settings.start_jd, settings.end_jd, settings.law)
                for i, lo in enumerate(range(0, len(stars), chunk))]
        found = dict(run(transits_of, jobs))
        transits = {k: np.concatenate([found[i][k] for i in range(len(jobs))]) for k in ("star", "t", "psi")}
        del found  # 16 bytes per transit, 2.6e7 transits at the paper's scale
        print(f"mcsweep: primary: {len(stars)} stars, {transits['t'].size} FoV transits found", flush=True)
    with prov.stage("observations"):
        data = prepare(settings, stars, transits)
        del transits
        release_free_memory()  # the blocks' build leaves free holes in the heap (1/3 of it at 3e5 stars)
    results, histories, extras, attitude_series = {}, [], {}, []
    # The factor search (experiment.primary.factor_grid) shares solutions with Table 3's priors.
    factors = {float(k): factor_label(k) for k in pri.factor_grid}
    # The solver's chunk work goes to the executor only on a Dask cluster (one client for
    # every solution, opened when the first one is needed): local joblib processes
    # re-receive every chunk's measurements per call, which costs more than the work
    # (measured 6.6x slower setup pass, 32000 stars; see mcsweep.solver.cg.solve_global).
    # On this machine the n_jobs workers are forked per solution and keep their share of
    # the blocks (mcsweep.solver.resident); results are the same bits either way.
    run = None
    workers = int(config.execution.n_jobs) if config.execution.backend in ("loky", "threading") else 1
    with contextlib.ExitStack() as cluster:
        for label in dict.fromkeys([*settings.priors, *factors.values()]):
            cid = _prior_id(label)
            with prov.stage(f"solve {label}"):
                res = store.read(cid)
                extra_file = run_dir / CHUNKS_DIR / f"{cid}.json"
                if res is None or not extra_file.exists():
                    if config.execution.backend == "dask":
                        if run is None:
                            run = cluster.enter_context(executor(config.execution))
                        res, hist, extra, series = solve_prior(settings, data, label, run=run,
                                                               chunk_stars=int(config.execution.chunk_stars))
                    else:
                        res, hist, extra, series = solve_prior(settings, data, label, workers=workers)
                    atomic_write_bytes(run_dir / CHUNKS_DIR / f"{cid}_history.csv", hist.to_csv(index=False).encode())
                    atomic_write_bytes(run_dir / CHUNKS_DIR / f"{cid}_attitude.csv",
                                       series.to_csv(index=False).encode())
                    atomic_write_bytes(extra_file, json.dumps(extra).encode())
                    store.write(cid, res)
                    release_free_memory()  # the solution's temporaries, before the next one
                    print(f"mcsweep: primary: prior {label}: {extra['iterations']} PCG iterations, converged "
                          f"{extra['converged']}, attitude error RMS {np.round(extra['attitude_rms_uas'], 2)} uas",
                          flush=True)
                results[label] = res
                histories.append(pd.read_csv(run_dir / CHUNKS_DIR / f"{cid}_history.csv"))
                att_file = run_dir / CHUNKS_DIR / f"{cid}_attitude.csv"
                if att_file.exists():  # absent only in a resumed run of an older version
                    attitude_series.append(pd.read_csv(att_file).assign(prior=label))
                extras[label] = json.loads(extra_file.read_text())
    with prov.stage("aggregate"):
        prov.cell_versions = dict(store.versions_read)
        table = table3_rows({k: results[k] for k in settings.priors}, pri.g_classes, settings.confidence)
        if factors:
            by_k = {k: results[lab] for k, lab in factors.items()}
            rng = np.random.default_rng(stream_seed(settings.seed, FACTOR_STREAM))
            fac = factor_rows(by_k, pri.g_classes, settings.confidence, n_resamples=pri.factor_resamples, rng=rng)
            k_all, flag = overall_factor(fac)
            fac = pd.concat([fac, pd.DataFrame([{"subset": "all", "g_class": "all", "k_min": k_all, "flag": flag}])],
                            ignore_index=True)
            atomic_write_bytes(run_dir / "primary_factor.csv", fac.to_csv(index=False).encode())
            atomic_write_bytes(run_dir / "primary_factor_curves.csv",
                               factor_curves(by_k, pri.g_classes).to_csv(index=False).encode())
        n_obs = data.n_measurements
        summary = pd.DataFrame([{"prior": k, **{kk: (json.dumps(v) if isinstance(v, list) else v)
                                                for kk, v in e.items()}} for k, e in extras.items()])
        summary["n_stars_solved"] = data.solved.size
        summary["n_measurements"] = n_obs
        summary["n_attitude_coefficients"] = 3 * data.spline.n_coef
        summary["knot_interval_hours"] = pri.knot_interval_hours
        summary["dead_fraction"] = data.dead_days / (settings.end_jd - settings.start_jd)
        counts = stars.groupby("class_key").size().to_dict()
        notes = [f"Confidence P = {settings.confidence:g}; {pri.mission_years:g} year(s) from {pri.mission_start} "
                 f"(TCB), dead time {100 * pri.dead_time_fraction:g} % in blocks of {pri.dead_time_block_days:g} d; "
                 f"scanning law '{config.scanning.name}'; sigma_F90: {pri.f90_formula}; R = {settings.ratio_R:g} /yr; "
                 f"reference epoch: {epoch['text']}.",
                 f"Stars: {pri.class_size} per class (paper 5e5), {counts.get(PRIMARY_KEY, 0)} primary sources "
                 f"(G >= {pri.primary_g_min:g}); {data.solved.size} with >= 1 transit, {n_obs} measurements; "
                 f"attitude: cubic spline, knot interval {pri.knot_interval_hours:g} h "
                 f"({3 * data.spline.n_coef} coefficients); true attitude = law + {pri.attitude_amplitude_mas:g} mas "
                 f"random spline rotation on a {pri.attitude_timescale_hours:g} h time scale.",
                 "PCG iterations / attitude error RMS (x, y, z) [uas] after the frame correction: "
                 + "; ".join(f"{k}: {e['iterations']} ({'converged' if e['converged'] else 'NOT converged'}), "
                             + ", ".join(f"{v:.2f}" for v in e["attitude_rms_uas"]) for k, e in extras.items())
                 + "."]
        outputs = {"table3.csv": table.to_csv(index=False), "table3.md": table3_markdown(table, settings.confidence,
                                                                                       notes),
                   "primary_convergence.csv": pd.concat(histories, ignore_index=True).to_csv(index=False),
                   "primary_summary.csv": summary.to_csv(index=False)}
        if attitude_series:
            outputs["primary_attitude_error.csv"] = pd.concat(attitude_series, ignore_index=True).to_csv(
                index=False)
        for name, text in outputs.items():
            atomic_write_bytes(run_dir / name, text.encode())
    prov.seeds["primary"] = {
        "population": "SeedSequence(seed, spawn_key=(42, 0, round(100*G0) or 0 for the primaries))",
        "dead_time": "SeedSequence(seed, spawn_key=(42, 1))",
        "true_attitude": "SeedSequence(seed, spawn_key=(42, 2))",
        "noise": "SeedSequence(seed, spawn_key=(42, 3))",
        "factor_bootstrap": "SeedSequence(seed, spawn_key=(42, 4))",
    }
    return run_dir / "table3.csv"
