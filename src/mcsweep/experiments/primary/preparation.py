"""The primary solution's data, prepared partition by partition and chunk by chunk (paper Sect. 4.2).

One sequence (:func:`prepare_data`) whatever runs it; a :class:`Partitions` says where the
table of stars is and runs the tasks there: in this process (:class:`~.local.InProcess`, the
whole table one partition) or on a Dask cluster's workers (:class:`~.cluster.OnCluster`, the
table in partitions of the sky, kept there with everything per star). Steps:

1. Per partition: its transits, and per star the live transits' count, mean live epoch and
   span (:func:`~.transits.partition_summary`); to the driver only the partition's number of
   solved stars and their live FoV transits (:func:`~.transits.partition_digest`), and with
   ``knot_transits`` what places the knots (:func:`~.knots.live_epochs`, the epochs sorted
   per partition, asked as one sorted array).
2. The solver's spline (:func:`~.truth.attitude_spline`) and the true attitude.
3. Per partition, given its first solved star: its measurements summed by solver block
   (:func:`~.transits.partition_block_counts`), from which each block's first measurement.
4. Each chunk of blocks (:class:`Layout`) built by :func:`~.blocks.build_chunk` from the
   partitions it overlaps: the same bits as any other chunking, since every block's noise
   has its own seed. What the driver keeps: where each block's stars and measurements sit,
   which coefficients have data and, where the chunks stay on workers, the attitude band.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Protocol, Sequence

import numpy as np

from ...solver import SOLVER_BLOCK_STARS
from .blocks import ChunkSpec
from .data import PreparedData
from .experiment import PrimarySettings, min_transits
from .knots import live_epochs
from .transits import first_rows, partition_block_counts, partition_digest
from .truth import attitude_spline, dead_time_of, true_attitude

__all__ = ["Built", "Layout", "Partitions", "prepare_data"]


@dataclasses.dataclass(frozen=True)
class Layout:
    """The solved stars in blocks of ``block_stars``: the first measurement of each block
    (``rows``), and per partition of the table its first star (``firsts``), first solved star
    (``solved_first``) and number of solved stars (``n_solved_p``)."""

    block_stars: int
    rows: np.ndarray
    n_rows: int
    firsts: np.ndarray
    solved_first: np.ndarray
    n_solved_p: np.ndarray
    with_noise: bool

    @property
    def n_solved(self) -> int:
        return int(self.n_solved_p.sum())

    @property
    def n_blocks(self) -> int:
        return -(-self.n_solved // self.block_stars)

    def stars_of(self, k: int) -> int:
        """Stars of block ``k`` (the last may be short)."""
        return min(self.block_stars, self.n_solved - k * self.block_stars)

    def chunk(self, blo: int, bhi: int, *, band: bool) -> tuple[ChunkSpec, np.ndarray]:
        """The task's spec of the chunk of blocks ``blo .. bhi - 1`` and the partitions it
        overlaps (their inputs follow the spec, in this order)."""
        bs, n_solved = self.block_stars, self.n_solved
        lo, hi = blo * bs, min(bhi * bs, n_solved)
        ends = self.solved_first + self.n_solved_p
        ps = np.flatnonzero((self.solved_first < hi) & (ends > lo) & (self.n_solved_p > 0))
        parts = tuple((int(self.firsts[p]), int(max(lo - self.solved_first[p], 0)),
                       int(min(hi, ends[p]) - self.solved_first[p])) for p in ps)
        blocks = tuple((k, k * bs, self.stars_of(k), int(self.rows[k])) for k in range(blo, bhi))
        return ChunkSpec(blocks=blocks, parts=parts, block_stars=bs, with_noise=self.with_noise, band=band), ps


@dataclasses.dataclass(frozen=True)
class Built:
    """What the driver keeps of the built chunks: the blocks (or where they sit), which spline
    coefficients have data, and the attitude band if it was summed where they were built."""

    blocks: list
    covered: np.ndarray
    naa_band: np.ndarray | None


class Partitions(Protocol):
    """Where the table of stars is, in partitions of consecutive stars (``first[p]``,
    ``sizes[p]``), and the tasks run there: ``submit(fn, *args)`` gives a handle of
    ``fn(*args)`` (handles among the arguments stand for their values), ``gather`` their
    values, ``shared(name, obj)`` a handle of an object every task may need."""

    first: np.ndarray
    sizes: np.ndarray

    def open(self, settings: PrimarySettings, dead, min_fov: int) -> None:
        """Search each partition's transits and summarise them (:func:`~.transits.partition_summary`)."""

    def table(self, p: int): ...

    def summary(self, p: int): ...

    def transits(self, p: int): ...

    def submit(self, fn: Callable, *args): ...

    def gather(self, handles: Sequence) -> list: ...

    def shared(self, name: str, obj): ...

    def epochs(self, handles: Sequence, start_jd: float, end_jd: float):
        """The partitions' sorted epochs (``handles``) as one sorted array, or an object that
        answers as one (:class:`~mcsweep.solver.attitude_spline.SortedEpochs`)."""

    def build(self, layout: Layout, settings: PrimarySettings, spline, truth: tuple, dead) -> Built:
        """Every chunk of ``layout`` built with :func:`~.blocks.build_chunk` and kept."""

    def data(self, **common) -> PreparedData:
        """The prepared data: ``common`` (:class:`~.data.PreparedData`'s fields) and what this
        executor keeps."""


def block_counts(where: Partitions, settings: PrimarySettings, solved_first: np.ndarray, n_blocks: int,
                 block_stars: int) -> np.ndarray:
    """Measurements per solver block, summed from the partitions' counts (step 3)."""
    per_block = np.zeros(n_blocks, dtype=np.int64)
    got = where.gather([where.submit(partition_block_counts, where.summary(p), where.table(p), int(solved_first[p]),
                                     block_stars, where.shared("settings", settings))
                        for p in range(len(where.first))])
    for k0, sums in got:
        per_block[k0:k0 + sums.size] += sums
    return per_block


def prepare_data(settings: PrimarySettings, where: Partitions, *, block_stars: int = SOLVER_BLOCK_STARS,
                 with_noise: bool = True) -> PreparedData:
    """Dead time, observations of the solved stars, truth and noisy measurements of the table
    ``where`` holds (module notes), made where it is; ``with_noise=False`` leaves the
    measurement noise out (tests)."""
    dead = dead_time_of(settings)
    where.open(settings, dead, min_transits(settings))
    n_parts = len(where.first)
    digests = where.gather([where.submit(partition_digest, where.summary(p)) for p in range(n_parts)])
    n_solved_p = np.array([d["n_solved"] for d in digests], dtype=np.int64)
    n_fov_transits = int(sum(d["n_fov"] for d in digests))
    solved_first = first_rows(n_solved_p)
    del digests
    epochs = None
    if settings.knot_transits is not None:  # knots placed by the solution's live FoV transits
        dead_shared = where.shared("dead", dead)
        epochs = where.epochs([where.submit(live_epochs, where.summary(p), where.transits(p), dead_shared,
                                            int(where.first[p])) for p in range(n_parts)],
                              settings.start_jd, settings.end_jd)
    spline = attitude_spline(settings, dead, epochs)
    del epochs
    n_solved = int(n_solved_p.sum())
    per_block = block_counts(where, settings, solved_first, -(-n_solved // block_stars), block_stars)
    layout = Layout(block_stars=block_stars, rows=first_rows(per_block), n_rows=int(per_block.sum()),
                    firsts=np.asarray(where.first), solved_first=solved_first, n_solved_p=n_solved_p,
                    with_noise=with_noise)
    truth = true_attitude(settings)
    built = where.build(layout, settings, spline, truth, dead)
    return where.data(blocks=built.blocks, spline=spline, true_attitude=truth, t_ref_jd=settings.t_ref_jd, dead=dead,
                      covered=built.covered, n_rows=layout.n_rows, n_stars=int(np.sum(where.sizes)),
                      n_solved=n_solved, n_fov_transits=n_fov_transits, naa_band=built.naa_band)
