"""The whole-sky secondary experiment (paper Sect. 4.1, Table 2) on the global path.

The science (per-chunk solutions, the table) lives in :mod:`mcsweep.experiments.secondary`
and :mod:`mcsweep.experiments.secondary_table`; the path every global experiment shares
(provenance, classes of stars, chunk store and resume, aggregation) in
:mod:`mcsweep.sweep.global_runner`. What is the secondary's own: the chunks of stars
(fixed noise blocks grouped by ``chunk_stars``) solved through the executor, each written
to ``secondary_chunks/`` as soon as it is done, and the tables Table 2, ``no_prior.csv``
and ``secondary_summary.csv``.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from ..experiments.global_classes import STAR_COLUMNS, class_key
from ..experiments.secondary import (SECONDARY_NOISE_BLOCK_STARS, CHUNKS_DIR, TAG, build_settings, class_summary, solve_chunk)
from ..experiments.secondary_table import no_prior_rows, table2_markdown, table2_rows
from .global_runner import GlobalExperiment, GlobalRun, run_global

__all__ = ["SECONDARY", "run_secondary"]


def _chunk_task(job):
    settings, g_class, chunk_id, first, stars, store = job
    store.write(chunk_id, solve_chunk(settings, g_class, first, stars))
    return chunk_id


def _chunk_id(g_class: float, lo: int, hi: int) -> str:
    return f"class{class_key(g_class):04d}_stars{lo:09d}-{hi:09d}"


def _plan(run: GlobalRun) -> list[tuple]:
    """(G0, chunk id, first, last) of every chunk: whole noise blocks, so chunking never
    changes a result (:data:`~mcsweep.experiments.secondary.SECONDARY_NOISE_BLOCK_STARS`)."""
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


#: The secondary experiment on the global path (:func:`~mcsweep.sweep.global_runner.run_global`).
SECONDARY = GlobalExperiment(
    kind="secondary", tag=TAG, chunks_dir=CHUNKS_DIR, build_settings=build_settings,
    groups=lambda sec: [(float(g), sec.class_size, class_key(g)) for g in sec.g_classes],
    compute=_compute, aggregate=_aggregate, result="table2.csv", population_bar="population classes",
    kept=lambda section, done, run_dir: f"{len(done)} solved chunk{'s' * (len(done) != 1)} of stars kept in {run_dir}",
    seeds={"population": "SeedSequence(seed, spawn_key=(41, 0, round(100*G0)))",
           "dilution": "key from SeedSequence(seed, spawn_key=(41, 1, round(100*G0))), hashed with the star index",
           "noise": f"SeedSequence(seed, spawn_key=(41, 2, round(100*G0), star index // {SECONDARY_NOISE_BLOCK_STARS}))"})


def run_secondary(config, raw_cfg: dict, run_dir, *, prov=None) -> Path:
    """Run (or resume) the experiment in ``run_dir``; returns the path of ``table2.csv``.

    Writes ``secondary_chunks/*.parquet`` (per-star results, one file per chunk) as it
    goes, then ``table2.csv``, ``table2.md``, ``no_prior.csv`` and
    ``secondary_summary.csv``.
    """
    return run_global(SECONDARY, config, raw_cfg, run_dir, prov=prov)
