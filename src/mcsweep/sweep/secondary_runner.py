"""Run the whole-sky secondary experiment (paper Sect. 4.1, Table 2) chunk by chunk.

The science (class selection, per-chunk solutions, the table) lives in
:mod:`mcsweep.experiments.secondary`; this module only schedules it: chunks of stars go
through the configured executor (joblib / Dask), each written atomically to
``secondary_chunks/`` as soon as it is done, so a killed run resumes; the tables are
written at the end.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..experiments.epoch import describe_reference_epoch
from ..experiments.secondary import (BLOCK_STARS, CHUNKS_DIR, POPULATION_STREAM, STAR_COLUMNS,
                                     build_settings, class_key, class_summary, select_class_stars,
                                     solve_chunk, stream_seed)
from ..experiments.secondary_table import no_prior_rows, table2_markdown, table2_rows
from ..population import make_source
from .execution import executor
from .progress import progress
from .provenance import Provenance
from .store import CellStore, atomic_write_bytes

__all__ = ["run_secondary"]


def _chunk_task(job):
    settings, g_class, chunk_id, first, stars, store = job
    store.write(chunk_id, solve_chunk(settings, g_class, first, stars))
    return chunk_id


def _chunk_id(g_class: float, lo: int, hi: int) -> str:
    return f"class{class_key(g_class):04d}_stars{lo:09d}-{hi:09d}"


def run_secondary(config, raw_cfg: dict, run_dir, *, prov=None) -> Path:
    """Run (or resume) the experiment in ``run_dir``; returns the path of ``table2.csv``.

    Writes ``secondary_chunks/*.parquet`` (per-star results, one file per chunk) as it
    goes, then ``table2.csv``, ``table2.md``, ``no_prior.csv`` and
    ``secondary_summary.csv``.
    """
    run_dir = Path(run_dir)
    prov = prov or Provenance(run_dir, raw_cfg, kind="secondary")
    prov.check_compatible()
    sec = config.experiment.secondary
    settings = build_settings(config)
    epoch = describe_reference_epoch(settings.reference_epoch, settings.start_jd, settings.end_jd)
    prov.derived["secondary"] = {"reference_epoch": epoch}
    with prov.stage("population"):
        source = make_source(dataclasses.asdict(config.population))
        bar = progress(len(sec.g_classes), desc="population classes", unit="classes",
                       enabled=config.execution.progress)
        classes = []
        for g in sec.g_classes:
            rng = np.random.default_rng(stream_seed(settings.seed, POPULATION_STREAM, class_key(g)))
            classes.append((float(g), select_class_stars(source, float(g), sec.class_size, rng)))
            bar.update(1)
        bar.close()
        del source  # the galaxy model's whole-sky tables (~0.5 GB) are not needed any more
    # Inputs are valid: claim the run directory for this config before any chunk is written,
    # so a killed run is resumed (and guarded against other configs) like a finished one.
    prov.write(with_manifest=False)
    chunk = BLOCK_STARS * math.ceil(config.execution.chunk_stars / BLOCK_STARS)
    store = CellStore(run_dir / CHUNKS_DIR, prov.hash,
                      accept_other_versions=config.resume.accept_other_versions)
    store.remove_stale_temporaries()  # left by a killed write, never a result
    plan = [(g, stars, _chunk_id(g, lo, min(lo + chunk, len(stars))), lo, min(lo + chunk, len(stars)))
            for g, stars in classes for lo in range(0, len(stars), chunk)]
    jobs = [(settings, g, cid, lo, {c: stars[c].to_numpy()[lo:hi] for c in STAR_COLUMNS}, store)
            for g, stars, cid, lo, hi in plan if store.read(cid) is None]
    with prov.stage("chunks"), executor(config.execution) as run:
        bar = progress(len(plan), initial=len(plan) - len(jobs), desc="secondary chunks", unit="chunks",
                       enabled=config.execution.progress)
        for _ in run(_chunk_task, jobs):
            bar.update(1)
        bar.close()

    with prov.stage("aggregate"):
        store.versions_read.clear()
        per_class, summary = [], []
        for g, stars in classes:
            parts = [store.read(cid) for gg, _, cid, _, _ in plan if gg == g]
            if any(p is None for p in parts):  # pragma: no cover - a worker wrote a bad file
                raise RuntimeError(f"a chunk of class G >= {g:g} has no valid result")
            results = pd.concat(parts, ignore_index=True)
            per_class.append((g, results))
            summary.append(class_summary(g, stars, results))
        prov.cell_versions = dict(store.versions_read)
        table = table2_rows(per_class, settings.confidence)
        no_prior = no_prior_rows(per_class, settings.confidence)
        summary = pd.DataFrame(summary)
        notes = [f"Confidence P = {settings.confidence:g}; dilution {sec.dilution:g}; "
                 f"{sec.mission_years:g} years from {sec.mission_start} (TCB); scanning law "
                 f"'{config.scanning.name}'; sigma_F90: {sec.f90_formula}; R = {settings.ratio_R:g} /yr; "
                 f"reference epoch: {epoch['text']}.",
                 "Stars per class: " + ", ".join(f"G >= {r['g_class']}: {r['n_stars']} (mean retained "
                                                 f"FoV transits {r['mean_fov_retained']:.2f})"
                                                 for r in summary.to_dict("records")) + "."]
        outputs = {"table2.csv": table.to_csv(index=False), "no_prior.csv": no_prior.to_csv(index=False),
                   "secondary_summary.csv": summary.to_csv(index=False),
                   "table2.md": table2_markdown(table, settings.confidence, notes, dilution=sec.dilution)}
        for name, text in outputs.items():
            atomic_write_bytes(run_dir / name, text.encode())
    prov.seeds["secondary"] = {
        "population": "SeedSequence(seed, spawn_key=(41, 0, round(100*G0)))",
        "dilution": "key from SeedSequence(seed, spawn_key=(41, 1, round(100*G0))), hashed with the star index",
        "noise": f"SeedSequence(seed, spawn_key=(41, 2, round(100*G0), star index // {BLOCK_STARS}))",
    }
    return run_dir / "table2.csv"
