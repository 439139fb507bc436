"""The sweep's unit of work, as a worker process runs it: the cells of one direction x G bin.

A worker imports this module (the task is pickled by reference) and what the cells need:
the population source, the pencil-beam cell and the result store, not the fit, the maps,
the report or the scanning law's integration, which only the parent uses, so a worker
starts sooner (docs/performance.md).
"""

from __future__ import annotations

import dataclasses

from ...population import make_source
from ...runtime.execution import keep_freed_arrays
from .pencil_beam import run_cell, transit_columns

__all__ = ["population_key", "population_source", "shipped_source", "warm_worker", "cell_task", "direction_g_jobs"]


def _freeze(d: dict) -> tuple:
    return tuple(sorted((k, _freeze(v) if isinstance(v, dict) else tuple(v) if isinstance(v, list) else v)
                        for k, v in d.items()))


def population_key(config) -> tuple:
    """The config's population section as a hashable key (:func:`population_source`)."""
    return _freeze(dataclasses.asdict(config.population))


#: The population sources of this process by :func:`population_key`, the last few configs'.
_SOURCES: dict[tuple, object] = {}
_MAX_SOURCES = 4


def population_source(key: tuple, built=None):
    """The population source of a :func:`population_key`: one per process and config
    (a catalogue is read once, the galaxy model's isochrones summed once). ``built``: the
    source of that key already built elsewhere (the parent's, :func:`warm_worker`), kept if
    this process has none yet."""
    source = _SOURCES.get(key)
    if source is None:
        source = built if built is not None else make_source(dict(key))
        _SOURCES[key] = source
        while len(_SOURCES) > _MAX_SOURCES:
            del _SOURCES[next(iter(_SOURCES))]
    return source


def shipped_source(source):
    """What :func:`warm_worker` sends a worker of the parent's population source: the galaxy
    model itself (0.1 MB pickled, 20 ms to unpickle against 0.35 s to build), not a catalogue
    (a worker reads that from its file rather than through a pipe)."""
    return source if getattr(source, "draws_from_density", False) else None


def warm_worker(job) -> None:
    """What a worker does before its first cell, while the parent computes the transits
    (:func:`mcsweep.runtime.execution.executor`'s ``warm_up``): take the parent's population
    source (:func:`shipped_source`) or build it, and load the compiled passes a cell runs, on a
    few stars whose results are dropped (each cell's streams are its own, so this changes
    none)."""
    import numpy as np

    from ...astrometry.shared_design import SharedDesignNormals

    pop_key, settings, built = job
    keep_freed_arrays()
    source = population_source(pop_key, built)
    rng = np.random.default_rng(0)
    if getattr(source, "draws_from_density", False):
        source.sample_cone(0.0, 0.0, 1.0, 12.0, 13.0, rng, max_stars=16, min_draw=16)
    design = rng.normal(size=(4, 5))
    normals = SharedDesignNormals.simulate(design, [np.ones(16), np.ones(16)], np.zeros((3, 16)), rng)
    scan = normals.prior_scan(settings.ratio_R)
    scan.inside_counts(settings.prior_grid_mas, settings.confidence, keys=True)
    scan.position_statistics(settings.prior_grid_mas[:1], settings.confidence)


def cell_task(job):
    """Run the cells of one direction x G bin (the colour-blind cell and its colour cells,
    which share their batches of stars); returns (cell_id, showcase, table bytes) per cell."""
    # The store travels with the job so a worker stamps the parent's code version.
    cells, transits, pop_key, settings, store, keep_scatter, radii = job
    keep_freed_arrays()  # every cell makes and frees the same megabyte arrays
    source = population_source(pop_key)
    draws: dict = {}
    out = []
    for cell, radius in zip(cells, radii):
        # The showcase cell (keep_scatter) feeds Figs. 1 and 3: statistics on its whole grid.
        table, scatter = run_cell(cell, transits, source, settings, keep_scatter=keep_scatter, radius_deg=radius,
                                  grid_statistics=True if keep_scatter else None, draws=draws, arrow=True)
        if scatter is not None:
            store.write(cell.cell_id + "_scatter", scatter)
        # The written bytes travel back: the aggregate reads them instead of the file (1.5 ms of
        # checksum and read per cell, 13 s of the colour sweep's 3361 cells).
        out.append((cell.cell_id, keep_scatter, store.write(cell.cell_id, table)))
    return out


def direction_g_jobs(cells, transits, pop_key, settings, store, radii) -> list[tuple]:
    """One job per direction x G bin: its cells in the order given (a resumed run's kept cells
    left out), with the direction's :func:`~.pencil_beam.transit_columns` (made once here)."""
    groups: dict[tuple, list] = {}
    for c in cells:
        groups.setdefault(c.key[:4], []).append(c)
    columns: dict[int, dict] = {}
    for group in groups.values():
        index = group[0].direction.index
        if index not in columns:
            columns[index] = transit_columns(transits[index])
    return [(group, columns[group[0].direction.index], pop_key, settings, store, False,
             [radii.get(c.cell_id) for c in group]) for group in groups.values()]
