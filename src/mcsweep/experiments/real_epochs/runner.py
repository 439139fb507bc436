"""The real-epochs experiment's run: inputs checked, truths, the subsets in chunks of sources
through the executor, then the tables.

In this order (as :func:`mcsweep.experiments.global_solution.run.run_global` does for the
global experiments):

1. the inputs read and checked, the fitted prior's run directory loaded, the truths solved:
   every user error is raised here, before anything is written; a run directory holding
   results of other input files (their SHA-256 in provenance) is refused in one line;
2. ``provenance.json`` written without manifest (the run directory is claimed for this
   config, so a killed run is resumed like a finished one);
3. stage ``subsets``: chunks of :data:`SOURCES_PER_CHUNK` sources, each a store entry
   (atomic Parquet with checksum; a rerun keeps the finished ones), solved through the
   configured executor. Every random number comes from a seed of the source's identity
   (:mod:`.subsets`), so chunking, workers and completion order change no bit;
4. stage ``aggregate``: ``real_epochs.csv`` and ``real_epochs_sources.csv`` written
   atomically, only now.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import UserInputError
from ...prior import Prior
from ...runtime.execution import executor
from ...runtime.progress import progress
from ...runtime.store import ResultStore, atomic_write_bytes
from ..global_solution.priors import prior_sigma_mas
from . import CHUNKS_DIR, SOURCES_TABLE, TABLE
from .inputs import Inputs, read_inputs
from .solutions import TRUTH_EPOCH_JD, ChunkSettings, Truth, solve_chunk, solve_truth
from .subsets import BOOTSTRAP_STREAM, DRAW_STREAM, TAG, UNITS, source_layout
from .table import HOLD_LIMIT_SIGMA, NO_TRUTH, cell_rows, prior_order, source_rows, star_classes, \
    transit_unit_weight_variance

__all__ = ["SOURCES_PER_CHUNK", "FITTED", "Prepared", "prepare", "chunk_plan", "compute", "aggregate", "run", "kept",
           "check_same_inputs"]

#: Sources per chunk (task and store entry). Why: a chunk's largest array is sources x draws
#: x CCD rows of its most-observed source (booleans, ~10 MB at 32 x 200 x 1555, the vendored
#: sample's largest), and the subsets' CCD rows at six visits (~150 per subset: ~7 MB per
#: source of float64 columns), so 32 sources stay below ~0.3 GB per worker. Results do not
#: depend on it (seeds are per source); a resumed run's finished chunks stay valid only with it.
SOURCES_PER_CHUNK = 32
#: The name of the sweep run's fitted prior (``fitted_prior``).
FITTED = "fitted"
#: The run directory's provenance record (mcsweep.command.provenance.PROVENANCE_FILE; the
#: command is a stage above the experiments, so its name is repeated here).
_PROVENANCE_FILE = "provenance.json"


@dataclass(frozen=True)
class Prepared:
    """What a run computes before writing anything."""

    inputs: Inputs
    truth: Truth
    #: Per source of ``inputs.sources``: the paper's sigma_F90 [mas], the class, the diagnostics.
    sigma_f90_mas: np.ndarray
    star_class: np.ndarray
    unit_weight_variance: np.ndarray
    #: prior -> (S,) parallax prior sigma [mas] (without 'none').
    sigma_mas: dict
    settings: ChunkSettings
    #: The table's prior names, 'none' last.
    priors: tuple


def _fitted(run_dir: str) -> Prior:
    try:
        return Prior.from_run(run_dir)
    except UserInputError as exc:
        raise UserInputError(f"experiment.real_epochs.fitted_prior: {exc}") from None


def prepare(config) -> Prepared:
    """Step 1 of the module notes: user errors raised here, nothing written."""
    sec = config.experiment.real_epochs
    fitted = _fitted(sec.fitted_prior) if sec.fitted_prior is not None else None
    inputs = read_inputs(sec.epoch_file, sec.sources_file)
    truth = solve_truth(inputs.obs)
    src = inputs.sources
    sigma_f90 = np.asarray(Prior.paper().sigma_parallax_mas(src.l_deg, src.b_deg, src.g_mag), float)
    sigma = {str(p): prior_sigma_mas(str(p), sigma_f90) for p in sec.priors}
    if fitted is not None:
        sigma[FITTED] = np.asarray(fitted.sigma_parallax_mas(src.l_deg, src.b_deg, src.g_mag), float)
    ratio_R = float(config.ratio_R)
    settings = ChunkSettings(seed=int(config.seed), draws=int(sec.draws),
                             sizes={"transits": tuple(int(k) for k in sec.transits),
                                    "visits": tuple(int(k) for k in sec.visits)},
                             priors=tuple(sigma), confidence=float(config.confidence), ratio_R=ratio_R)
    return Prepared(inputs=inputs, truth=truth, sigma_f90_mas=sigma_f90,
                    star_class=star_classes(truth, sigma_f90, ratio_R),
                    unit_weight_variance=transit_unit_weight_variance(inputs.obs, truth), sigma_mas=sigma,
                    settings=settings, priors=prior_order(sigma))


def chunk_plan(prep: Prepared) -> list[tuple[str, np.ndarray]]:
    """(chunk id, indices of its sources in ``inputs.sources``): the sources with a truth, in
    id order, :data:`SOURCES_PER_CHUNK` at a time."""
    solved = np.flatnonzero(prep.truth.ok)
    return [(f"sources{lo:07d}-{min(lo + SOURCES_PER_CHUNK, solved.size):07d}", solved[lo:lo + SOURCES_PER_CHUNK])
            for lo in range(0, solved.size, SOURCES_PER_CHUNK)]


def _chunk_task(job):
    settings, chunk_id, obs, truth_x, sigma, store = job
    store.write(chunk_id, solve_chunk(settings, obs, truth_x, sigma))
    return chunk_id


def _pending(store: ResultStore, chunk_ids) -> list[str]:
    # Checking is not using: these reads do not count in the code versions of the results
    # (as GlobalRun.pending).
    seen = Counter(store.versions_read)
    todo = [cid for cid in chunk_ids if store.read(cid) is None]
    store.versions_read = seen
    return todo


def compute(prep: Prepared, store: ResultStore, execution) -> None:
    """Fill ``store`` with the subsets of every chunk not finished yet (step 3)."""
    plan = chunk_plan(prep)
    todo = set(_pending(store, [cid for cid, _ in plan]))
    obs = prep.inputs.obs
    starts = np.searchsorted(obs.source_id, prep.inputs.sources.source_id)
    ends = np.searchsorted(obs.source_id, prep.inputs.sources.source_id, side="right")
    jobs = []
    for cid, idx in plan:
        if cid not in todo:
            continue
        # the CCD rows of the chunk's sources: each source's block [start, end), concatenated
        lengths = ends[idx] - starts[idx]
        rows = np.repeat(starts[idx] - np.r_[0, np.cumsum(lengths)[:-1]], lengths) + np.arange(lengths.sum())
        jobs.append((prep.settings, cid, obs.take(rows), prep.truth.x[idx],
                     {p: s[idx] for p, s in prep.sigma_mas.items()}, store))
    if not jobs:
        return
    bar = progress(len(plan), initial=len(plan) - len(jobs), desc="real-epoch chunks", unit="chunks",
                   enabled=bool(execution.progress))
    with executor(execution) as run_tasks:
        for _ in run_tasks(_chunk_task, jobs):
            bar.update(1)
    bar.close()


def sources_frame(prep: Prepared) -> pd.DataFrame:
    """One row per source: direction, G, its observations, its truth, the prior and its class."""
    src, tr = prep.inputs.sources, prep.truth
    lay = source_layout(prep.inputs.obs)
    first = np.searchsorted(prep.inputs.obs.source_id, src.source_id)
    pm = np.hypot(tr.x[:, 3], tr.x[:, 4])
    sigma_pm = prep.settings.ratio_R * prep.sigma_f90_mas
    return pd.DataFrame({
        "source_id": src.source_id, "ra_deg": src.ra_deg, "dec_deg": src.dec_deg, "l_deg": src.l_deg,
        "b_deg": src.b_deg, "phot_g_mean_mag": src.g_mag, "n_transits": lay.n_items["transits"],
        "n_visits": lay.n_items["visits"], "n_visibility_periods": tr.n_visibility_periods,
        "time_span_yr": tr.time_span_yr, "excess_noise_mas": prep.inputs.obs.excess_noise_mas[first],
        "truth_ok": tr.ok, "truth_parallax_mas": tr.x[:, 2], "truth_pmra_masyr": tr.x[:, 3],
        "truth_pmdec_masyr": tr.x[:, 4], "truth_parallax_error_mas": tr.error[:, 2],
        "truth_pmra_error_masyr": tr.error[:, 3], "truth_pmdec_error_masyr": tr.error[:, 4],
        "transit_unit_weight_variance": prep.unit_weight_variance, "sigma_f90_mas": prep.sigma_f90_mas,
        "sigma_pm_f90_masyr": sigma_pm, "parallax_over_sigma_f90": np.abs(tr.x[:, 2]) / prep.sigma_f90_mas,
        "pm_over_sigma_pm": pm / sigma_pm, "star_class": prep.star_class})


def aggregate(prep: Prepared, store: ResultStore, sec) -> dict[str, str]:
    """The tables' text from the finished chunks (step 4)."""
    parts = [store.read(cid) for cid, _ in chunk_plan(prep)]
    if any(p is None for p in parts):  # pragma: no cover - a worker wrote a bad file
        raise RuntimeError(f"a chunk of {CHUNKS_DIR} has no valid result")
    results = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()
    classes = dict(zip(prep.inputs.sources.source_id.tolist(), prep.star_class.tolist()))
    st = prep.settings
    table = cell_rows(results, classes, prep.priors, st.sizes, seed=st.seed, confidence=st.confidence,
                      n_boot=int(sec.bootstrap))
    per_source = source_rows(results, sources_frame(prep), prep.priors, st.sizes, confidence=st.confidence)
    return {TABLE: table.to_csv(index=False), SOURCES_TABLE: per_source.to_csv(index=False)}


def check_same_inputs(run_dir: Path, digests: dict) -> None:
    """A run directory holding results of other input files is refused (step 1)."""
    path = run_dir / _PROVENANCE_FILE
    if not path.exists():
        return
    try:
        old = json.loads(path.read_text()).get("derived", {}).get("real_epochs", {}).get("input_sha256")
    except (OSError, ValueError):
        return  # the command's own check reads it too and names the problem
    changed = [k for k in digests if old and old.get(k) not in (None, digests[k])]
    if changed:
        raise UserInputError(f"run directory {run_dir} holds results of other input files (the bytes of "
                             f"experiment.real_epochs.{changed[0]} changed: sha256 {old[changed[0]][:12]} -> "
                             f"{digests[changed[0]][:12]}); expected the same files to resume, or a new hydra.run.dir")


def _derived(prep: Prepared) -> dict:
    """What the report states of the sample (provenance ``derived.real_epochs``)."""
    inp, src = prep.inputs, prep.inputs.sources
    lay = source_layout(inp.obs)
    ok = prep.truth.ok

    def span(v):
        v = np.asarray(v)
        kind = int if v.dtype.kind in "iu" else float
        return [kind(v.min()), kind(v.max())] if v.size else [None, None]

    return {"epoch_file": inp.epoch_file, "sources_file": inp.sources_file, "sample": inp.sample,
            "input_sha256": dict(inp.digests), "n_sources": int(src.source_id.size),
            "n_without_truth": int((~ok).sum()), "n_held": int((prep.star_class == "held").sum()),
            "n_not_held": int((prep.star_class == "not_held").sum()), "g_range_mag": span(src.g_mag),
            "transit_range": span(lay.n_items["transits"]), "visit_range": span(lay.n_items["visits"]),
            "time_span_range_yr": span(prep.truth.time_span_yr), "n_ccd": int(len(inp.obs)),
            "truth_epoch": f"J2017.5 (TCB, JD {TRUTH_EPOCH_JD})", "hold_limit_sigma": HOLD_LIMIT_SIGMA,
            "priors": list(prep.priors), "no_truth_class": NO_TRUTH}


def run(config, raw_cfg: dict, run_dir, prov) -> Path:
    """Run (or resume) the experiment in ``run_dir`` (module notes); returns ``real_epochs.csv``."""
    run_dir = Path(run_dir)
    prov.check_compatible()
    prep = prepare(config)
    check_same_inputs(run_dir, prep.inputs.digests)
    prov.derived["real_epochs"] = _derived(prep)
    prov.write(with_manifest=False)
    store = ResultStore(run_dir / CHUNKS_DIR, prov.hash, accept_other_versions=config.resume.accept_other_versions)
    store.remove_stale_temporaries()  # left by a killed write, never a result
    with prov.stage("subsets"):
        compute(prep, store, config.execution)
    with prov.stage("aggregate"):
        texts = aggregate(prep, store, config.experiment.real_epochs)
        prov.cell_versions = dict(store.versions_read)
        for name, text in texts.items():
            atomic_write_bytes(run_dir / name, text.encode())
    prov.seeds["real_epochs"] = {
        "subsets": f"SeedSequence(seed, spawn_key=({TAG}, {DRAW_STREAM}, source_id, unit index "
                   f"({', '.join(f'{i} {u}' for i, u in enumerate(UNITS))}), k))",
        "bootstrap": f"SeedSequence(seed, spawn_key=({TAG}, {BOOTSTRAP_STREAM}, unit index, k, class index "
                     "(0 held, 1 not_held, 2 all)))"}
    return run_dir / TABLE


def kept(config, config_hash: str, run_dir) -> str:
    """What a rerun keeps, for the one line of a stopped command."""
    done = ResultStore(Path(run_dir) / CHUNKS_DIR, config_hash).finished()
    return f"{len(done)} finished chunk{'s' * (len(done) != 1)} of sources kept in {run_dir}"
