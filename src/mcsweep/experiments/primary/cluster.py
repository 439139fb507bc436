"""The primary solution's data built, kept and solved on the workers of a Dask cluster.

With ``execution=dask`` the driver holds nothing per star: the table of stars (:mod:`~.sky`:
partitions in sky order), the transits, the solver's blocks, the measurements, every
per-star array of a solution and each star's outcome are made and kept on the cluster; the
driver holds the attitude (spline, band, Schur factor, CG vectors), the frame, a few numbers
per partition, block and chunk, and one part of the per-star results at a time while it
writes them (:class:`~.results.StarParts`). The solver's chunks
(:mod:`mcsweep.solver.dask_resident`) are the futures of the tasks that built them.

:class:`OnCluster` runs :func:`~.preparation.prepare_data`, the sequence the driver runs in
this process too (:class:`~.local.InProcess`), with its tasks on the workers: the results
stay there unless said otherwise. The chunks (aligned runs of leaves of blocks,
:func:`~mcsweep.solver.problem.solver_chunks`) are spread over the workers in contiguous
shares, each built by one task from the partitions, summaries and transits it overlaps
(worker to worker) with :func:`~.blocks.build_chunk`; back to the driver come the chunks'
attitude bands, summed on each worker where the fixed tree adds them
(:class:`~mcsweep.solver.reduction.AlignedPartials`), and which coefficients they touch. The
transits are then let go.

Per prior (:func:`~.prior_solution.solve_prior`, the sequence data held in this process go
through too): the prior's label is sent; the prior sigma of each star, the inverses, frame
weights, solution, the frame rotator's sums and each star's outcome are made on the workers
(:mod:`~.chunk_tasks`, summed in the same tree, so the same bits as a forked or in-process
run). The per-star results come to the driver one part (:data:`~.results.PART_STARS` stars)
at a time, their columns gathered from the partitions (:meth:`ClusterData.star_columns`).

A lost worker takes its chunks and the state of a solution: its chunks are built again from
the partitions (transit search included; a lost partition is made again from the classes,
:mod:`~.sky`) and the solution restarts from its first pass
(:class:`~mcsweep.solver.executors.ChunksLost`), with the same bits (tested by killing a worker
mid-solve); a loss while the parts are written solves the prior again (same bits).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Callable

import numpy as np

from ...solver import SOLVER_BLOCK_STARS
from ...solver.blocks import BlockSpan
from ...solver.dask_resident import DaskChunks, is_loss, live_workers
from ...solver.executors import retried
from ...solver.problem import solver_chunks
from ...solver.reduction import run_level, share_of, sum_partials
from .blocks import build_chunk, fold_infos
from .data import PreparedData, SolverChunks
from .experiment import PrimarySettings
from .knots import ClusterEpochs
from .preparation import Built, Layout, prepare_data
from .sky import SkyPartitions, alive
from .transits import partition_columns, partition_summary, partition_transits

__all__ = ["ClusterData", "OnCluster", "prepare_on_cluster"]


def _first(pair):
    return pair[0]


def _second(pair):
    return pair[1]


class _Table:
    """The table of stars on the cluster and each partition's per-star transit summary
    (:func:`~.transits.partition_summary`), made again after a loss: the partitions from their classes
    (:meth:`~.sky.SkyPartitions.ensure`), the summaries by searching the partitions'
    transits again (the tasks they came from are not kept by the scheduler)."""

    def __init__(self, sky: SkyPartitions, search: Callable, summarise: Callable):
        self.sky, self._search, self._summarise = sky, search, summarise
        self.found = [search(p) for p in range(len(sky))]
        self.summaries = [summarise(p, f) for p, f in enumerate(self.found)]

    def ensure(self) -> None:
        """Every partition and summary there (made again where a worker took them)."""
        remade = self.sky.ensure()
        for p, fut in enumerate(self.summaries):
            if remade or not alive(fut):
                self.summaries[p] = self._summarise(p, self._search(p))

    def transits(self, p: int):
        """A future of partition ``p``'s transits: the first search's while kept, else a new one."""
        if self.found is not None and alive(self.found[p]):
            return self.found[p]
        return self._search(p)

    def release_transits(self) -> None:
        self.found = None


class _Shared:
    """Objects every task may need (dead time, scanning law, settings, spline, true attitude),
    scattered once, and again if a lost worker took them (the scheduler keeps one copy of
    scattered data: its memory manager drops the replicas of a broadcast)."""

    def __init__(self, client):
        self.client = client
        self.futures: dict = {}

    def __call__(self, name: str, obj):
        fut = self.futures.get(name)
        if fut is None or fut.status != "finished":
            (fut,) = self.client.scatter([obj], hash=False)
            self.futures[name] = fut
        return fut


class OnCluster:
    """The table ``sky`` on the workers of the Dask ``client``, in partitions of the sky:
    :class:`~.preparation.Partitions` whose tasks run there (a handle is a future) and whose
    chunks, of ``chunk_stars`` stars, are built and kept there (module notes)."""

    def __init__(self, client, sky: SkyPartitions, chunk_stars: int | None):
        self.client, self.sky, self.chunk_stars = client, sky, chunk_stars
        self.first, self.sizes = sky.first, sky.sizes
        self.scattered = _Shared(client)
        self.found = self.kept = None

    def open(self, settings: PrimarySettings, dead, min_fov: int) -> None:
        client, sky, shared = self.client, self.sky, self.scattered

        def search(p: int):
            return client.submit(partition_transits, sky.futures[p], int(sky.first[p]), settings.start_jd,
                                 settings.end_jd, shared("law", settings.law), pure=False)

        def summarise(p: int, transits):
            return client.submit(partition_summary, transits, shared("dead", dead), int(sky.first[p]),
                                 int(sky.sizes[p]), min_fov, pure=False)

        self.found = _Table(sky, search, summarise)

    def table(self, p: int):
        return self.sky.futures[p]

    def summary(self, p: int):
        return self.found.summaries[p]

    def transits(self, p: int):
        return self.found.transits(p)

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def gather(self, handles) -> list:
        return self.client.gather(list(handles))

    def shared(self, name: str, obj):
        return self.scattered(name, obj)

    def epochs(self, handles, start_jd: float, end_jd: float):
        # placed by the epochs where they are (the knots come back, not the epochs)
        return ClusterEpochs(self.client, list(handles), start_jd, end_jd)

    def build(self, layout: Layout, settings: PrimarySettings, spline, truth: tuple, dead) -> Built:
        client, table, shared = self.client, self.found, self.scattered
        ranges = solver_chunks(layout.n_blocks, layout.block_stars, layout.n_rows, spline.n_coef, self.chunk_stars)

        def submit(ci: int, workers=None):
            """The task building chunk ``ci`` (after a loss: from the partitions and summaries made
            again where the lost worker took them, the transits searched again; the live workers
            asked again unless given)."""
            table.ensure()
            spec, ps = layout.chunk(*ranges[ci], band=True)
            inputs = [x for p in ps for x in (self.sky.futures[p], table.summaries[p], table.transits(p))]
            workers = workers or live_workers(client)
            # spread over the workers (memory) in contiguous shares of the chunks, so each worker
            # sums its chunks' outputs before they travel (DaskChunks.reduced), not where the
            # transits are
            owner = share_of(ci, len(ranges), len(workers))
            return client.submit(build_chunk, spec, shared("settings", settings), shared("spline", spline),
                                 shared("truth", truth), shared("dead", dead), *inputs, pure=False,
                                 workers=[workers[owner]], allow_other_workers=True)

        def rebuild(ci: int):
            return client.submit(_first, submit(ci), pure=False)

        first = live_workers(client)  # one scheduler query for the first build
        built = [submit(ci, first) for ci in range(len(ranges))]
        chunks = [client.submit(_first, b, pure=False) for b in built]
        infos = [client.submit(_second, b, pure=False) for b in built]
        del built
        naa_band, covered, rows_of = self._fold(ranges, infos, spline.n_coef)
        del infos
        table.release_transits()  # a lost chunk searches its partitions again (rebuild)
        spans = [BlockSpan(first=k * layout.block_stars, n=layout.stars_of(k), rows=slice(r0, r1))
                 for ci, (blo, bhi) in enumerate(ranges) for k, (r0, r1) in zip(range(blo, bhi), rows_of[ci])]
        self.kept = dict(ranges=[tuple(r) for r in ranges], chunks=DaskChunks(client, chunks, rebuild=rebuild),
                         solved_first=layout.solved_first)
        return Built(blocks=spans, covered=covered,
                     naa_band=np.zeros((0, 0)) if naa_band is None else naa_band)

    def _fold(self, ranges, infos, n_coef: int) -> tuple:
        """The chunks' build results (:func:`~.blocks.build_chunk`) folded on the workers that
        hold them, each adding its chunks' bands where the fixed tree adds them: a few bands
        reach the driver, not one per chunk (the same bits). Returns (attitude band, covered
        coefficients, each chunk's blocks' rows)."""
        from distributed import wait

        client = self.client
        levels = [run_level(lo, hi) for lo, hi in ranges]
        wait(infos)
        holders = client.who_has(infos)
        groups: dict = {}
        for ci, f in enumerate(infos):
            groups.setdefault(min(holders.get(f.key) or [""]), []).append(ci)
        folded = client.gather([client.submit(fold_infos, [ranges[ci][0] for ci in cis], [levels[ci] for ci in cis],
                                              n_coef, *[infos[ci] for ci in cis], pure=False,
                                              workers=[w] if w else None, allow_other_workers=True)
                                for w, cis in groups.items()])
        covered = np.zeros(n_coef, dtype=bool)
        rows_of = {}
        for (_, cov, block_rows), cis in zip(folded, groups.values()):
            covered[cov] = True
            rows_of.update(zip(cis, block_rows))
        return sum_partials(f[0] for f in folded), covered, rows_of

    def data(self, **common) -> "ClusterData":
        return ClusterData(sky=self.sky, table=self.found, client=self.client, **self.kept, **common)


@dataclasses.dataclass(kw_only=True)
class ClusterData(PreparedData):
    """:class:`~.data.PreparedData` whose stars and measurements are kept on a Dask cluster's
    workers (``blocks`` are :class:`~mcsweep.solver.blocks.BlockSpan` s): the table there
    (partitions and their transit summaries, made again after a loss), the solver's chunks of
    block ``ranges`` and the client. Nothing per star is held here."""

    sky: SkyPartitions
    table: object            # the partitions' transit summaries (made again after a loss)
    solved_first: np.ndarray  # first solved star of each partition
    client: object
    ranges: list
    chunks: DaskChunks

    on_cluster = True

    def resident(self, client, ranges) -> DaskChunks:
        """The solver's chunks of block ``ranges`` kept on the workers of ``client``: those
        built there (no other chunking or client)."""
        if client is not self.client or [tuple(r) for r in ranges] != self.ranges:
            raise ValueError("these data were built on a cluster for other chunks or another client")
        return self.chunks

    def solver_chunks(self, *, chunk_stars=None, workers: int = 1, dask_client=None) -> SolverChunks:
        """The chunks built on the cluster of ``dask_client`` (``workers`` unused), which must
        be the ones of ``chunk_stars`` stars (:meth:`resident`)."""
        if dask_client is None:
            raise ValueError("these data live on a cluster's workers: solve them with its dask_client")
        spans = self.blocks
        if not spans:
            raise ValueError("no star with a transit to solve")
        ranges = solver_chunks(len(spans), spans[0].n, self.n_measurements, self.spline.n_coef, chunk_stars)
        return SolverChunks(ranges, self.resident(dask_client, ranges))

    def star_columns(self, rows: slice) -> tuple[dict, int]:
        """The columns gathered from the partitions holding stars ``rows`` (made again after a loss)."""
        sky, table, client = self.sky, self.table, self.client
        ends = sky.first + sky.sizes
        overlap = np.flatnonzero((sky.first < rows.stop) & (ends > rows.start))

        def columns():
            table.ensure()
            return client.gather([client.submit(partition_columns, sky.futures[p], table.summaries[p],
                                                max(rows.start - sky.first[p], 0),
                                                min(rows.stop, ends[p]) - sky.first[p], pure=False) for p in overlap])

        got = retried(columns, is_loss, lambda: time.sleep(1.0))  # (a moment for the scheduler's news of the loss)
        cols = {c: np.concatenate([g[c] for g in got]) for c in ("class_key", "n_fov", "n_fov_scheduled",
                                                              "span_days", "solved")}
        lo = int(self.solved_first[overlap[0]] + got[0]["solved_before"]) if len(overlap) else 0
        return cols, lo


def prepare_on_cluster(settings: PrimarySettings, sky: SkyPartitions, client, *, chunk_stars: int | None,
                       block_stars: int = SOLVER_BLOCK_STARS, with_noise: bool = True) -> ClusterData:
    """:func:`~.preparation.prepare_data` of the table ``sky`` (partitions on the workers of the
    Dask ``client``) with the transits, blocks and measurements made and kept there (module
    notes): the same data, bit for bit, as of the whole table in this process, whose
    ``resident(client, ranges)`` for the solver's chunks of ``chunk_stars`` stars are the
    chunks already there. A worker lost while they are made makes them again from the start."""
    return retried(lambda: prepare_data(settings, OnCluster(client, sky, chunk_stars), block_stars=block_stars,
                                         with_noise=with_noise), is_loss)
