"""The real-sky validation (Hipparcos stars as truth) on the global path.

The science lives in :mod:`mcsweep.experiments.real_sky.experiment`; the shared path (provenance,
chunk store and resume, aggregation, atomic tables) in :mod:`mcsweep.experiments.global_solution.run`.
What is its own: the stars come from the Hipparcos 2 catalogue instead of the galaxy
model (:attr:`GlobalExperiment.draw`), each star's sigma_F90 of every prior (and a colour
prior's mean) is computed in the parent (so tasks carry numbers, not priors), chunks of whole noise blocks are
solved through the executor, and the tables ``real_sky.csv``, ``real_sky.md``,
``real_sky_errors.csv`` and ``real_sky_complete.csv`` (the fractions carried over to the
complete sky, :mod:`mcsweep.experiments.real_sky.complete`) are written.
"""

from __future__ import annotations

import math

import pandas as pd

from .experiment import (REAL_SKY_NOISE_BLOCK_STARS, TAG, build_settings, draw_stars, error_rows,
                                    prior_queries, solve_chunk, star_columns, table_markdown, table_rows)
from .complete import complete_markdown, complete_rows
from . import CHUNKS_DIR, TABLES
from ..global_solution.run import GlobalExperiment, GlobalRun

__all__ = ["REAL_SKY"]

#: The star columns a chunk needs.
_COLUMNS = ("hip", "ra", "dec", "l", "b", "phot_g_mean_mag", "parallax", "pmra", "pmdec", "parallax_error",
            "pmra_error", "pmdec_error")


def _draw(settings, section, seed_of) -> list:
    stars = draw_stars(settings)
    for column, values in prior_queries(settings, stars).items():
        stars[column] = values
    return [(settings.g_min, 0, stars)]


def _chunk_task(job):
    settings, chunk_id, first, stars, store = job
    store.write(chunk_id, solve_chunk(settings, first, stars))
    return chunk_id


def _plan(run: GlobalRun) -> list[tuple]:
    """(chunk id, first, last): whole noise blocks, so chunking never changes a result."""
    chunk = REAL_SKY_NOISE_BLOCK_STARS * math.ceil(run.config.execution.chunk_stars / REAL_SKY_NOISE_BLOCK_STARS)
    n = len(run.classes[0][2])
    return [(f"stars{lo:07d}-{min(lo + chunk, n):07d}", lo, min(lo + chunk, n)) for lo in range(0, n, chunk)]


def _compute(run: GlobalRun) -> None:
    plan = _plan(run)
    todo = set(run.pending([cid for cid, _, _ in plan]))
    stars = run.classes[0][2]
    cols = list(_COLUMNS) + star_columns(run.settings)
    jobs = [(run.settings, cid, lo, {c: stars[c].to_numpy()[lo:hi] for c in cols}, run.store)
            for cid, lo, hi in plan if cid in todo]
    run.map("chunks", _chunk_task, jobs, desc="real-sky chunks", done=len(plan) - len(jobs))


def _aggregate(run: GlobalRun, _computed=None) -> dict[str, str]:
    settings, stars = run.settings, run.classes[0][2]
    results = pd.concat(run.read_all([cid for cid, _, _ in _plan(run)]), ignore_index=True)
    table = table_rows(stars, results, settings)
    errors = error_rows(stars, settings)
    obs = run.config.observations
    notes = [f"Confidence P = {settings.confidence:g}; Hipparcos 2 (van Leeuwen 2007, CDS I/311) stars with "
             f"{settings.g_min:g} <= G < {settings.g_max:g}: {len(stars)} of {stars.attrs.get('n_in_range', len(stars))}"
             f"; transits of the scanning law '{run.config.scanning.name}' from {obs.start} to {obs.end} (TCB); "
             f"priors {', '.join(f'{p} ({s})' for p, s in settings.priors)} x {settings.factor:g}"
             + (f" (with each star's Gaia DR3 BP-RP: {', '.join(settings.colour)}; centred on the run's mean: "
                f"{', '.join(settings.with_mean) or 'none'})" if settings.colour else "") + "; "
             f"R = {settings.ratio_R:g} /yr; reference epoch: {run.epoch['text']}.",
             "Each cell: fraction inside [68 % Clopper-Pearson interval] / P-th percentile of |estimated - true "
             "position| [mas] (n = stars solved); truth = Hipparcos parallax and proper motion."]
    complete = complete_rows(stars, results, settings)
    md = table_markdown(table, errors, settings, notes) + "\n".join([""] + complete_markdown(complete, settings.confidence))
    return {"real_sky.csv": table.to_csv(index=False), "real_sky_errors.csv": errors.to_csv(index=False),
            "real_sky_complete.csv": complete.to_csv(index=False), "real_sky.md": md}


#: The real-sky validation on the global path (:func:`~mcsweep.experiments.global_solution.run.run_global`).
REAL_SKY = GlobalExperiment(
    kind="real_sky", tag=TAG, chunks_dir=CHUNKS_DIR, build_settings=build_settings,
    groups=lambda sec: [], draw=_draw, compute=_compute, aggregate=_aggregate, tables=TABLES,
    kept=lambda section, done, run_dir: f"{len(done)} solved chunk{'s' * (len(done) != 1)} of Hipparcos stars kept in {run_dir}",
    seeds={"population": "SeedSequence(seed, spawn_key=(43, 0, 0)) (subset with max_stars)",
           "noise": f"SeedSequence(seed, spawn_key=(43, 2, crc32(case), star index // {REAL_SKY_NOISE_BLOCK_STARS}))",
           "perturbed_truth": f"SeedSequence(seed, spawn_key=(43, 3, star index // {REAL_SKY_NOISE_BLOCK_STARS}))"})
