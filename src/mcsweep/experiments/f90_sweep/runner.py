"""Run the sigma_F90 sweep: every cell once, resumably, on the configured backend.

Stages (each timed in the provenance): population source, transits of every
direction (one scanning-law evaluation for all directions, in this process), the cells
(in worker processes, each written atomically as soon as it is done, so an
interrupted sweep resumes where it stopped), the single-direction showcase (Figs. 1-3),
and aggregation: ``cells.parquet``, the fit of Eqs. 14-17 over the sky (Sect. 3.4,
:mod:`mcsweep.experiments.f90_sweep.fit`: ``f90_cells.csv``, ``coefficients.csv``,
``rms_dex.csv``, ``eq14_terms.csv``) and ``prior_maps.fits``. Aggregation runs on every
call, so a sweep resumed after all its cells were done still writes them. The report
(:mod:`mcsweep.report`) only reads these files.
"""

from __future__ import annotations

import logging

import dataclasses
import gc
import io
from pathlib import Path

import numpy as np
import pandas as pd
from astropy.time import Time

from ...astrometry.noise_models import noise_model
from ...errors import UserInputError
from .colour_fit import colour_tables, means_table
from .fit import colour_blind, f90_table, fit_all, fit_tables, prior_maps_for_run
from .jobs import cell_task, direction_g_jobs, population_key, population_source, shipped_source, warm_worker
from .pencil_beam import CellSettings, cell_radius
from ...population import CatalogueSource
from ...prior.maps import MAPS_FILE
from ...prior.run_record import MEANS_FILE, read_record
from ...scanning import ScanningLaw, find_transits
from ...scanning.timescale import tcb_jd
from . import CELLS_DIR, SHOWCASE_DIR
from .cells import Cell, Direction, enumerate_cells, sky_directions
from .conf import SkyConf
from ...runtime.execution import executor
from ...runtime.progress import progress, stage_line
from ...runtime.store import ResultStore, atomic_write_bytes, concat_parquet

__all__ = ["build_settings", "run_sweep", "write_fit", "fit_rows", "showcase_cell", "showcase_groups",
           "SHOWCASE_GROUPS_FILE"]

#: The showcase direction's distinct transits (one row per group), for the report's Fig. 3.
SHOWCASE_GROUPS_FILE = "groups.csv"


def build_settings(config) -> CellSettings:
    g = config.prior_grid
    grid = tuple(float(v) for v in np.geomspace(g.min_mas, g.max_mas, g.n))
    obs, cell, sc = config.observations, config.cell, config.experiment.showcase
    return CellSettings(
        prior_grid_mas=grid,
        cases={k: tuple(int(i) for i in v) for k, v in obs.cases.items()},
        f90_case=obs.f90_case,
        confidence=config.confidence,
        ratio_R=config.ratio_R,
        beam_radius_deg=cell.beam_radius_deg,
        max_stars=cell.max_stars,
        min_stars=cell.min_stars,
        max_radius_deg=cell.max_radius_deg,
        interpolation=cell.interpolation,
        n_bootstrap=cell.n_bootstrap,
        grid_statistics=cell.grid_statistics,
        reference_epoch=obs.reference_epoch,
        fixed_epoch_tcb_jd=tcb_jd(obs.fixed_epoch, "observations.fixed_epoch"),
        noise=noise_model(config.noise),
        seed=config.seed,
        scatter_priors_mas=(sc.tight_prior_mas, sc.loose_prior_mas),
        colour_axis=bool(config.prior_model.colour_edges),
        mean=bool(config.prior_model.mean),
    )


def showcase_groups(transits: pd.DataFrame, law: ScanningLaw | None = None) -> pd.DataFrame:
    """One row per distinct transit (visit) of a direction: group, first and last UTC, FoVs, psi,
    and (with ``law``) the scanning-law segment of its first transit."""
    g = transits.groupby("group", sort=True, observed=True)
    out = g.agg(first_tcb_jd=("tcb_jd", "first"), last_tcb_jd=("tcb_jd", "last"),
                fovs=("fov", lambda f: "".join(f.astype(str))),
                scan_angle_deg=("scan_angle_deg", "first")).reset_index()
    for col in ("first", "last"):
        out[f"{col}_utc"] = Time(out[f"{col}_tcb_jd"].to_numpy(float), format="jd", scale="tcb").utc.iso
    cols = ["group", "first_utc", "last_utc", "fovs", "scan_angle_deg"]
    if law is not None:
        out["segment"] = law.segment_labels(out["first_tcb_jd"].to_numpy(float))
        cols.append("segment")
    return out[cols]


def showcase_cell(config) -> Cell:
    sc = config.experiment.showcase
    d = sky_directions(SkyConf(name="showcase", kind="list", frame="icrs",
                               directions=[[sc.ra_deg, sc.dec_deg]]))[0]
    return Cell(dataclasses.replace(d, index=-1), sc.g_min, sc.g_max)


def _import_report_modules() -> None:
    """Import the report's modules (matplotlib, the prior; a second) while the workers run the
    cells, when this process only waits, rather than after them; without the collector (no
    callback of another library runs meanwhile to catch a Ctrl-C in it and swallow it). A
    failure is left to the report, which imports them again."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        from . import section  # noqa: F401
    except Exception:
        pass
    finally:
        if enabled:
            gc.enable()


def direction_transits(config, directions: list[Direction], law: ScanningLaw | None = None
                       ) -> dict[int, pd.DataFrame]:
    """FoV transits of every direction, keyed by Direction.index (``law``: the configured
    scanning law if already built, else built here)."""
    if not directions:
        return {}
    law = law if law is not None else ScanningLaw.from_config(dataclasses.asdict(config.scanning))
    ra = np.array([d.ra_deg for d in directions])
    dec = np.array([d.dec_deg for d in directions])
    start = tcb_jd(config.observations.start, "observations.start")
    end = tcb_jd(config.observations.end, "observations.end")
    tr = find_transits(ra, dec, start, end, law=law)
    groups = {int(i): g.reset_index(drop=True) for i, g in tr.groupby("source_index", sort=False)}
    empty = tr.iloc[:0]
    return {d.index: groups.get(i, empty) for i, d in enumerate(directions)}


def run_sweep(config, raw_cfg: dict, run_dir: Path, *, prov) -> Path:
    """Run (or resume) the sweep of ``config`` (a checked :class:`mcsweep.command.schema.Config`)
    in ``run_dir`` with ``prov``, its :class:`~mcsweep.command.provenance.Provenance`; returns
    the path of ``cells.parquet``."""
    run_dir = Path(run_dir)
    prov.check_compatible()
    pop = population_key(config)
    with prov.stage("population_source"):
        # Built here first so a bad catalogue fails before any file is written (or worker started).
        source = population_source(pop)
    settings = build_settings(config)
    _check_colours(config, source)
    law = _scanning_law(config, prov)
    cells = enumerate_cells(config.sky, config.magnitudes, config.prior_model.colour_edges)
    keep = config.resume.accept_other_versions
    store = ResultStore(run_dir / CELLS_DIR, prov.hash, accept_other_versions=keep)
    show = showcase_cell(config) if config.experiment.showcase.enabled else None
    show_store = ResultStore(run_dir / SHOWCASE_DIR, prov.hash, accept_other_versions=keep)
    for st in (store, show_store):  # run start: no other writer may be active in run_dir
        st.remove_stale_temporaries()

    # Cells kept from an earlier run, read and verified once (the aggregate reuses them).
    kept = {c.cell_id: t for c in cells if (t := store.read_table(c.cell_id)) is not None}
    todo = [c for c in cells if c.cell_id not in kept]
    show_todo = show is not None and (show_store.read(show.cell_id) is None
                                      or show_store.read(show.cell_id + "_scatter") is None)
    # The workers start (imports, the population source, the compiled passes) while this
    # process computes the transits, if there are cells to compute; release_workers: their
    # memory is free for the aggregate and the report.
    warm = (warm_worker, (pop, settings, shipped_source(source))) if todo or show_todo else None
    with executor(config.execution, release_workers=True, warm_up=warm) as run:
        radii = _catalogue_radii(source, todo + ([show] if show is not None else []), settings)
        # Inputs are valid: claim the run directory for this config before any cell is written,
        # so a killed run is resumed (and guarded against other configs) like a finished one.
        prov.write(with_manifest=False)
        transits = _transits_of(config, prov, todo + ([show] if show_todo else []), law)
        if show_todo:
            (run_dir / SHOWCASE_DIR).mkdir(exist_ok=True)
            atomic_write_bytes(run_dir / SHOWCASE_DIR / SHOWCASE_GROUPS_FILE,
                               showcase_groups(transits[show.direction.index], law).to_csv(index=False).encode())
        jobs = direction_g_jobs(todo, transits, pop, settings, store, radii)
        if show_todo:
            jobs.insert(0, ([show], transits[show.direction.index], pop, settings, show_store, True,
                            [radii.get(show.cell_id)]))
        n_all = len(cells) + (show is not None)
        fresh: dict[str, bytes] = {}
        with prov.stage("cells"):
            bar = progress(n_all, initial=n_all - sum(len(j[0]) for j in jobs), desc="cells", unit="cells",
                           enabled=config.execution.progress)
            report_imported = False
            for done in run(cell_task, jobs):
                for cell_id, showcase, data in done:
                    if not showcase:
                        fresh[cell_id] = data
                bar.update(len(done))
                if not report_imported:
                    _import_report_modules()
                    report_imported = True
            bar.close()
    with prov.stage("aggregate"):
        missing = [c.cell_id for c in cells if c.cell_id not in kept and c.cell_id not in fresh]
        if missing:  # pragma: no cover - would mean a worker returned no table
            raise RuntimeError(f"{len(missing)} cells have no valid result, e.g. {missing[0]}")
        # Decoded one at a time as the aggregate writes them (memory: one row group of cells).
        tables = (kept.pop(c.cell_id) if c.cell_id in kept else store.decode(fresh.pop(c.cell_id)) for c in cells)
        return _aggregate(run_dir, tables, store, prov, nside=config.prior_maps.nside, settings=settings)


def _check_colours(config, source) -> None:
    """A colour axis needs each star's BP-RP, which only the galaxy model draws."""
    edges = config.prior_model.colour_edges
    if edges and isinstance(source, CatalogueSource):
        raise UserInputError(
            f"prior_model.colour_edges={list(edges)} needs each star's BP-RP, which population=catalogue "
            f"({source.path.name}) does not give; expected population=galaxy_model or prior_model=direction_g")


def _scanning_law(config, prov) -> ScanningLaw:
    """The configured law; where the sweep's interval lies outside its segments, the
    extrapolation is logged and recorded (``derived.scanning``) for the report."""
    law = ScanningLaw.from_config(dataclasses.asdict(config.scanning))
    note = law.extrapolation_note(tcb_jd(config.observations.start, "observations.start"),
                                  tcb_jd(config.observations.end, "observations.end"))
    prov.derived["scanning"] = {"extrapolated": note}
    if note:
        logging.getLogger("mcsweep").warning(note)
    return law


def _catalogue_radii(source, cells: list[Cell], settings: CellSettings) -> dict[str, float]:
    """Beam radius per cell id for a catalogue (each call scans the table, so only here), and
    a one-line refusal naming the first cell the catalogue does not cover, before any cell
    is computed; {} for the galaxy model."""
    radii: dict[str, float] = {}
    if not isinstance(source, CatalogueSource):
        return radii
    for c in cells:
        d = c.direction
        radius, n = cell_radius(source, c, settings)
        radii[c.cell_id] = radius
        if n < 1:
            raise UserInputError(
                f"catalogue {source.path.name}: no star within {radius:.3g} deg of (l, b) = "
                f"({d.l_deg:.2f}, {d.b_deg:.2f}) with {c.g_min:g} <= phot_g_mean_mag < {c.g_max:g}; "
                "expected a catalogue covering every cell of the sweep (choose sky/magnitudes to match)")
    return radii


def _transits_of(config, prov, cells: list[Cell], law: ScanningLaw) -> dict[int, pd.DataFrame]:
    """The FoV transits of the directions of ``cells`` (stage ``transits``, with its lines)."""
    dirs = {c.direction.index: c.direction for c in cells}
    enabled = config.execution.progress
    if dirs:
        stage_line("transits", f"scanning law over {len(dirs)} direction{'s' * (len(dirs) != 1)}, "
                   f"{config.observations.start} to {config.observations.end} (TCB)", enabled=enabled)
    with prov.stage("transits"):
        transits = direction_transits(config, list(dirs.values()), law)
    if dirs:
        n_tr = sum(len(t) for t in transits.values())
        stage_line("transits", f"{n_tr} FoV transits found in {prov.timings['transits']:.1f} s", enabled=enabled)
    return transits


def _aggregate(run_dir: Path, tables, store: ResultStore, prov, *, nside: int, settings: CellSettings) -> Path:
    """``cells.parquet`` from every finished cell's table (``tables``: an iterable in the cells'
    order), then the fit and the maps (:func:`write_fit`)."""
    out = run_dir / "cells.parquet"
    # The cells' Arrow tables joined and written as they are: one DataFrame per cell cost 5.4 s
    # of the colour sweep's 3361 cells, and one DataFrame of them all, converted and read back
    # whole, 0.4 GB of the parent's peak memory.
    data = concat_parquet(tables)
    prov.cell_versions = dict(store.versions_read)  # counted as the tables were decoded
    atomic_write_bytes(out, data)
    # The fit reads the cells as cells.parquet holds them (what a later reader gets).
    write_fit(run_dir, fit_rows(data, settings.f90_case), nside=nside, f90_case=settings.f90_case)
    prov.seeds["cells"] = ("stars: SeedSequence(seed, spawn_key=(*key, 0)); noise of a case (five "
                           "standard normals per star, astrometry.shared_design): "
                           "SeedSequence(seed, spawn_key=(*key, 1, crc32(case name))); bootstrap of "
                           "sigma_F90: SeedSequence(seed, spawn_key=(*key, 2)); "
                           "key = (l*1e4, (b+90)*1e4, 100*g_min, 100*g_max)")
    if settings.colour_axis:
        prov.seeds["colour_cells"] = ("a colour cell's key appends (100*(bp_rp_min+10), 100*(bp_rp_max+10)); its "
                                      "stars are the stars of its BP-RP bin in the batches of its direction x G "
                                      "bin: batch i from SeedSequence(seed, spawn_key=(*key[:4], stream, 5, i)), "
                                      "stream 0 for the stars and 3 for the prior's mean")
    if settings.mean:
        prov.seeds["prior_mean"] = ("the prior's centre: mean of an independent draw, SeedSequence(seed, "
                                    "spawn_key=(*key, 3)); quasars' noise: SeedSequence(seed, spawn_key=(*key, 4))")
    return out


def fit_rows(cells_parquet, f90_case: str) -> pd.DataFrame:
    """The rows of a sweep's ``cells.parquet`` (a path or its bytes) that :func:`write_fit` reads:
    every case at sigma_F90 and the F90 case on the prior grid, a fifth of the rows (the
    colour sweep's whole table takes 0.4 GB in memory). Every cell has both (a case without
    transits has its grid rows too), and a cell's scalar columns are the same on all its rows."""
    src = io.BytesIO(cells_parquet) if isinstance(cells_parquet, bytes) else cells_parquet
    return pd.read_parquet(src, filters=[[("at_f90", "==", True)], [("case", "==", f90_case)]])


def write_fit(run_dir: Path, cells: pd.DataFrame, *, nside: int, f90_case: str) -> None:
    """Fit Eqs. 14-17 to a sweep's cells (Sect. 3.4) and write the fit's tables and
    ``prior_maps.fits`` into ``run_dir`` (each file whole or not at all).

    What it writes besides the colour-blind fit follows the prior model of the run's record
    (:func:`mcsweep.prior.run_record.read_record`, the ``provenance.json`` the sweep wrote
    first): the colour files with a colour axis, the means with a mean-centred prior. The maps
    come after ``coefficients.csv``: they are drawn from the prior read back from it
    (:func:`mcsweep.experiments.f90_sweep.fit.prior_maps_for_run`). ``nside`` is not part of
    the config hash, so a rerun redraws the maps from the same fit at the configured nside.
    """
    run_dir = Path(run_dir)
    record = read_record(run_dir)
    f90 = f90_table(cells)
    fit = fit_all(colour_blind(f90))
    tables = fit_tables(fit)
    if record.colour_edges:
        tables.update(colour_tables(f90, fit.fitted, cells, f90_case))
    if record.mean:
        tables[MEANS_FILE] = means_table(f90)
    for name, table in tables.items():
        atomic_write_bytes(run_dir / name, table.to_csv(index=False).encode())
    atomic_write_bytes(run_dir / MAPS_FILE, prior_maps_for_run(run_dir, fit, nside=nside))
