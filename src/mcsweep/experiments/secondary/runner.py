"""The whole-sky secondary experiment (paper Sect. 4.1, Table 2) on the global path.

The science (per-chunk solutions, the table) lives in :mod:`mcsweep.experiments.secondary.experiment`
and :mod:`mcsweep.experiments.secondary.table`; the path every global experiment shares
(provenance, classes of stars, chunk store and resume, aggregation) in
:mod:`mcsweep.experiments.global_solution.run`. What is the secondary's own: the chunks of stars
(fixed noise blocks grouped by ``chunk_stars``) solved through the executor, each written
to ``secondary_chunks/`` as soon as it is done, and the tables Table 2, ``no_prior.csv``
and ``secondary_summary.csv``.
"""

from __future__ import annotations

import math

import pandas as pd

from ..global_solution.classes import STAR_COLUMNS, class_key
from .experiment import (SECONDARY_NOISE_BLOCK_STARS, TAG, build_settings, class_summary, solve_chunk)
from .table import no_prior_rows, table2_markdown, table2_rows
from . import CHUNKS_DIR, TABLES
from ..global_solution.run import GlobalExperiment, GlobalRun

__all__ = ["SECONDARY"]


def _chunk_task(job):
    settings, g_class, chunk_id, first, stars, store = job
    store.write(chunk_id, solve_chunk(settings, g_class, first, stars))
    return chunk_id


def _chunk_id(g_class: float, lo: int, hi: int) -> str:
    return f"class{class_key(g_class):04d}_stars{lo:09d}-{hi:09d}"


def _plan(run: GlobalRun) -> list[tuple]:
    """(G0, chunk id, first, last) of every chunk: whole noise blocks, so chunking never
    changes a result (:data:`~mcsweep.experiments.secondary.experiment.SECONDARY_NOISE_BLOCK_STARS`)."""
    chunk = SECONDARY_NOISE_BLOCK_STARS * math.ceil(run.config.execution.chunk_stars / SECONDARY_NOISE_BLOCK_STARS)
    return [(g, _chunk_id(g, lo, min(lo + chunk, len(stars))), lo, min(lo + chunk, len(stars)))
            for g, _, stars in run.classes for lo in range(0, len(stars), chunk)]


def _compute(run: GlobalRun) -> None:
    plan = _plan(run)
    todo = set(run.pending([cid for _, cid, _, _ in plan]))
    stars = {g: df for g, _, df in run.classes}
    jobs = [(run.settings, g, cid, lo, {c: stars[g][c].to_numpy()[lo:hi] for c in STAR_COLUMNS}, run.store)
            for g, cid, lo, hi in plan if cid in todo]
    run.map("chunks", _chunk_task, jobs, desc="secondary chunks", done=len(plan) - len(jobs))


def _aggregate(run: GlobalRun, _computed=None) -> dict[str, str]:
    plan, sec, settings = _plan(run), run.section, run.settings
    per_class, summary = [], []
    for g, _, stars in run.classes:
        results = pd.concat(run.read_all([cid for gg, cid, _, _ in plan if gg == g]), ignore_index=True)
        per_class.append((g, results))
        summary.append(class_summary(g, stars, results))
    table = table2_rows(per_class, settings.confidence)
    summary = pd.DataFrame(summary)
    notes = [run.conditions(f"dilution {sec.dilution:g}; {sec.mission_years:g} years from {sec.mission_start} (TCB)"),
             "Stars per class: " + ", ".join(f"G >= {r['g_class']}: {r['n_stars']} (mean retained "
                                             f"FoV transits {r['mean_fov_retained']:.2f})"
                                             for r in summary.to_dict("records")) + "."]
    return {"table2.csv": table.to_csv(index=False),
            "no_prior.csv": no_prior_rows(per_class, settings.confidence).to_csv(index=False),
            "secondary_summary.csv": summary.to_csv(index=False),
            "table2.md": table2_markdown(table, settings.confidence, notes, dilution=sec.dilution)}


#: The secondary experiment on the global path (:func:`~mcsweep.experiments.global_solution.run.run_global`).
SECONDARY = GlobalExperiment(
    kind="secondary", tag=TAG, chunks_dir=CHUNKS_DIR, build_settings=build_settings,
    groups=lambda sec: [(float(g), sec.class_size, class_key(g)) for g in sec.g_classes],
    compute=_compute, aggregate=_aggregate, tables=TABLES, population_bar="population classes",
    kept=lambda section, done, run_dir: f"{len(done)} solved chunk{'s' * (len(done) != 1)} of stars kept in {run_dir}",
    seeds={"population": "SeedSequence(seed, spawn_key=(41, 0, round(100*G0)))",
           "dilution": "key from SeedSequence(seed, spawn_key=(41, 1, round(100*G0))), hashed with the star index",
           "noise": f"SeedSequence(seed, spawn_key=(41, 2, round(100*G0), star index // {SECONDARY_NOISE_BLOCK_STARS}))"})
