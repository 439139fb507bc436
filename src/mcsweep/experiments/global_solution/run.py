"""The one path every global experiment runs along (paper Sect. 4: Tables 2 and 3).

A global experiment (the secondary solution, Sect. 4.1; the primary solution, Sect.
4.2; the real-sky validation with Hipparcos stars, :mod:`mcsweep.experiments.real_sky.experiment`) is
a :class:`GlobalExperiment`: what is specific to it. :func:`run_global` owns the rest, in
this order:

1. provenance: refuse a run directory of another config; record the resolved reference
   epoch under ``derived.<kind>``;
2. stage ``population``: the experiment's classes of stars
   (:func:`~mcsweep.experiments.global_solution.classes.draw_classes`, seeds ``(tag, 0, class
   key)``); then ``provenance.json`` is written without manifest, which claims the run
   directory for this config before any result exists, so a killed run is resumed (and
   guarded against other configs) like a finished one;
3. the chunk store ``<chunks_dir>/`` (atomic Parquet files with checksums; temporaries
   of a killed write removed): the experiment's ``compute`` fills it in stages of its
   own, skipping what is finished (:meth:`GlobalRun.pending`), through the configured
   executor (:meth:`GlobalRun.map`), and returns what its tables need besides the store;
4. stage ``aggregate``: the experiment's ``aggregate`` turns the store (and what
   ``compute`` returned) into its tables; each is written atomically, only now, so a
   table never describes a partial run;
5. the seeds of the experiment, the code versions of the results read, returned with the
   path of the main table.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from collections import Counter
from pathlib import Path
from typing import Callable

import pandas as pd

from .classes import POPULATION_STREAM, draw_classes
from .settings import spawn
from ...population import make_source
from ...runtime.execution import executor, in_process
from ...runtime.progress import progress
from ...runtime.store import ResultStore, atomic_write_bytes

__all__ = ["GlobalExperiment", "GlobalRun", "run_global", "kept_chunks"]


@dataclasses.dataclass(frozen=True)
class GlobalExperiment:
    """What a global experiment adds to :func:`run_global`."""

    #: Run kind in provenance and the config section ``experiment.<kind>``.
    kind: str
    #: First element of every spawn key of the experiment (41: Sect. 4.1, 42: Sect. 4.2).
    tag: int
    #: Sub-directory of the run directory holding the chunk store.
    chunks_dir: str
    #: config -> the experiment's settings (a GlobalSettings); raises UserInputError.
    build_settings: Callable
    #: experiment.<kind> section -> [(G0, number of stars, class key), ...] to draw.
    groups: Callable
    #: The experiment's own stages: fill the chunk store (GlobalRun -> what aggregate needs).
    compute: Callable
    #: (GlobalRun, what compute returned) -> {file name: text} of the tables.
    aggregate: Callable
    #: What provenance records under ``seeds.<kind>``.
    seeds: dict
    #: The result files its stages write (``aggregate``'s tables among them), the main one first.
    tables: tuple[str, ...]
    #: Description of a progress bar over the classes being drawn (None: no bar).
    population_bar: str | None = None
    #: (section, finished chunk ids, run_dir) -> what a rerun keeps, for the line of a
    #: stopped command (:func:`~mcsweep.runtime.interruption.kept_in_run`).
    kept: Callable = lambda section, done, run_dir: (
        f"{len(done)} finished chunk{'s' * (len(done) != 1)} kept in {run_dir}")
    #: (settings, section, seed_of) -> the classes [(G0, key, stars), ...] when the stars do
    #: not come from the configured population (the real-sky validation's Hipparcos
    #: stars); None: :attr:`groups` drawn from ``config.population``.
    draw: Callable | None = None
    #: config -> whether :attr:`compute` draws the classes itself, on a cluster's workers (the
    #: primary solution with ``execution=dask``, so that the stars never reach the driver);
    #: :func:`run_global` then only checks the population config and leaves ``classes`` empty.
    draws_on_workers: Callable = lambda config: False


@dataclasses.dataclass
class GlobalRun:
    """One run of a global experiment: what its stages share."""

    config: object
    run_dir: Path
    #: The run's provenance record (:class:`mcsweep.command.provenance.Provenance`).
    prov: object
    settings: object
    #: The resolved reference epoch (:func:`~mcsweep.experiments.global_solution.epoch.describe_reference_epoch`).
    epoch: dict
    #: (G0, class key, stars) per group of :attr:`GlobalExperiment.groups`, in order.
    classes: list
    store: ResultStore

    @property
    def section(self):
        return getattr(self.config.experiment, self.prov.kind)

    @property
    def chunks(self) -> Path:
        return self.store.directory

    def pending(self, chunk_ids) -> list[str]:
        """The chunks without a finished result (resume); checking is not using, so these
        reads do not count in the code versions of the results (``cell_code_versions``)."""
        seen = Counter(self.store.versions_read)
        todo = [cid for cid in chunk_ids if self.store.read(cid) is None]
        self.store.versions_read = seen
        return todo

    def read_all(self, chunk_ids) -> list[pd.DataFrame]:
        """The finished results of ``chunk_ids``, in order."""
        parts = [self.store.read(cid) for cid in chunk_ids]
        if any(p is None for p in parts):  # pragma: no cover - a worker wrote a bad file
            raise RuntimeError(f"a chunk of {self.chunks.name} has no valid result")
        return parts

    def map(self, stage: str, task: Callable, jobs: list, *, desc: str | None = None, done: int = 0,
            release_workers: bool = False) -> list:
        """``task`` of every job through the configured executor in provenance stage ``stage``,
        results in completion order; ``desc``: a progress bar over ``done`` + len(jobs) chunks."""
        out = []
        with self.prov.stage(stage), executor(self.config.execution, release_workers=release_workers) as run:
            bar = progress(done + len(jobs), initial=done, desc=desc, unit="chunks",
                           enabled=self.config.execution.progress) if desc else None
            for r in run(task, jobs):
                out.append(r)
                if bar is not None:
                    bar.update(1)
            if bar is not None:
                bar.close()
        return out

    def conditions(self, specific: str) -> str:
        """The first note of a table: P, what is ``specific`` to the experiment (mission,
        losses), the law, the sigma_F90 formula, R and the reference epoch."""
        return (f"Confidence P = {self.settings.confidence:g}; {specific}; scanning law "
                f"'{self.config.scanning.name}'; sigma_F90: {self.section.f90_formula}; "
                f"R = {self.settings.ratio_R:g} /yr; reference epoch: {self.epoch['text']}.")


def _draw_population(experiment: GlobalExperiment, config, settings, section, kind: str) -> list:
    """The classes of ``experiment.groups`` drawn from the configured population."""
    population = dataclasses.asdict(config.population)
    make_source(population)  # a bad population config: its one line before a bar or a worker starts
    groups = experiment.groups(section)
    bar = progress(len(groups), desc=experiment.population_bar, unit="classes",
                   enabled=config.execution.progress) if experiment.population_bar else None
    execution = config.execution
    # The galaxy model's classes are tasks of the executor: the whole-sky tables (~0.5 GB) and
    # the draw's temporaries (1.4 GB peak at 3 x 5e5 stars) stay in the workers, which are let
    # go afterwards. A catalogue is read here (its path is the driver's; one read for all classes).
    here = population.get("name") != "galaxy_model" or in_process(execution)
    with contextlib.nullcontext() if here else executor(execution, release_workers=True) as run:
        classes = draw_classes(population, groups,
                               lambda key: spawn(settings.seed, experiment.tag, POPULATION_STREAM, key),
                               size_key=f"experiment.{kind}.class_size", run=run, bar=bar)
    if bar is not None:
        bar.close()
    return classes


def kept_chunks(experiment: GlobalExperiment, config, config_hash: str, run_dir) -> str:
    """What a rerun of ``config`` in ``run_dir`` keeps, as the middle of a stopped command's line."""
    done = set(ResultStore(Path(run_dir) / experiment.chunks_dir, config_hash).finished())
    return experiment.kept(getattr(config.experiment, experiment.kind), done, Path(run_dir))


def run_global(experiment: GlobalExperiment, config, raw_cfg: dict, run_dir, *, prov) -> Path:
    """Run (or resume) ``experiment`` in ``run_dir`` (module notes) with ``prov``, the run's
    :class:`~mcsweep.command.provenance.Provenance`; returns its main table's path."""
    run_dir = Path(run_dir)
    kind = experiment.kind
    prov.check_compatible()
    settings = experiment.build_settings(config)
    epoch = settings.describe_epoch()
    prov.derived[kind] = {"reference_epoch": epoch}
    note = settings.law.extrapolation_note(settings.start_jd, settings.end_jd)
    prov.derived["scanning"] = {"extrapolated": note}
    if note:
        logging.getLogger("mcsweep").warning(note)
    section = getattr(config.experiment, kind)
    with prov.stage("population"):
        if experiment.draw is not None:
            classes = experiment.draw(settings, section,
                                      lambda key: spawn(settings.seed, experiment.tag, POPULATION_STREAM, key))
        elif experiment.draws_on_workers(config):
            make_source(dataclasses.asdict(config.population))  # a bad population config: its one line now
            classes = []
        else:
            classes = _draw_population(experiment, config, settings, section, kind)
    prov.write(with_manifest=False)
    store = ResultStore(run_dir / experiment.chunks_dir, prov.hash,
                      accept_other_versions=config.resume.accept_other_versions)
    store.remove_stale_temporaries()  # left by a killed write, never a result
    run = GlobalRun(config=config, run_dir=run_dir, prov=prov, settings=settings, epoch=epoch, classes=classes,
                    store=store)
    computed = experiment.compute(run)
    with prov.stage("aggregate"):
        outputs = experiment.aggregate(run, computed)
        unlisted = set(outputs) - set(experiment.tables)
        if unlisted:  # pragma: no cover - a programming error in a new experiment
            raise RuntimeError(f"{kind} writes {sorted(unlisted)}, which its tables do not list")
        prov.cell_versions = dict(store.versions_read)
        for name, text in outputs.items():
            atomic_write_bytes(run_dir / name, text.encode())
    prov.seeds[kind] = dict(experiment.seeds)
    return run_dir / experiment.tables[0]
