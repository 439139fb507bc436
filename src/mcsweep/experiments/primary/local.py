"""The primary solution's data held in this process, and its solutions here or on forked workers.

:class:`InProcess` runs :func:`~.preparation.prepare_data` in this process: the whole table is
one partition (its transits searched beforehand, in chunks through the run's executor,
:func:`~.transits.transits_of`), every task is called at once, and the chunks are built one
block at a time, their measurements written into one array (memory flat: a block's
temporaries at a time). :class:`LocalData` holds every star's arrays and gives the solver's
chunks as views of them, held here (:class:`~mcsweep.solver.executors.HeldChunks`: a prior
solved in this process or on forked workers) or sent once to a Dask cluster
(:meth:`LocalData.resident`); the prior's solution is the one sequence of
:func:`~.prior_solution.solve_prior`, as for data kept on a cluster.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ...solver import SOLVER_BLOCK_STARS, GlobalProblem
from ...solver.blocks import att_band
from ...solver.calibration import BasicAngleColumns, calibration_design
from ...solver.executors import HeldChunks
from ...solver.problem import solver_chunks
from ...solver.reduction import pairwise_sum, share_of
from .blocks import build_chunk
from .chunk_tasks import with_stars
from .data import PreparedData, SolverChunks
from .experiment import PrimarySettings
from .preparation import Built, Layout, prepare_data
from .transits import partition_summary, with_transit_columns

__all__ = ["InProcess", "LocalData", "prepare"]


@dataclasses.dataclass(kw_only=True)
class LocalData(PreparedData):
    """:class:`~.data.PreparedData` with every star's arrays in this process."""

    stars: pd.DataFrame      # STAR_COLUMNS + 'class_key' (round(100 G0), 0 = primary) + 'n_fov',
    #                          'epoch_offset_yr' (mean live epoch - reference), 'span_days' (live transits)
    solved: np.ndarray       # indices into ``stars`` of the stars in the solution
    normals: np.ndarray      # (n_solved, 5, 5) data normal matrices of the solved stars
    h: np.ndarray            # normalised measurements (observed minus computed from the law), problem order
    x_true: np.ndarray       # (n_solved, 5)
    mean_tcb_jd: np.ndarray  # (n_solved,) mean live epochs of the solved stars [TCB JD]
    calibration: BasicAngleColumns | None = None  # the basic-angle variation's design, problem order
    cached_problem: GlobalProblem | None = dataclasses.field(default=None, repr=False)
    sent: tuple | None = dataclasses.field(default=None, repr=False)  # ((client, ranges), DaskChunks)

    def border_names(self) -> list | None:
        return None if self.calibration is None else self.calibration.names()

    def problem(self, prior_diagonal) -> GlobalProblem:
        """The global problem under ``prior_diagonal`` held here (tests, diagnostics; the
        solutions are made on the chunks, :meth:`solver_chunks`): assembled once from the
        blocks, then only the per-star inverses and frame weights change from prior to prior
        (:meth:`GlobalProblem.with_prior`, bit-identical to a new problem)."""
        if self.cached_problem is None:
            st = self.stars
            self.cached_problem = GlobalProblem.from_blocks(
                self.blocks, self.normals, prior_diagonal, st["ra"].to_numpy()[self.solved],
                st["dec"].to_numpy()[self.solved], n_coef=self.spline.n_coef, n_measurements=self.n_measurements,
                naa_band=self.naa_band)
        else:
            self.cached_problem = self.cached_problem.with_prior(prior_diagonal)
        return self.cached_problem

    def solver_chunks(self, *, chunk_stars=None, workers: int = 1, dask_client=None) -> SolverChunks:
        """The solver's chunks of the data held here (views of their arrays): held in this
        process for its ``workers`` (:class:`~mcsweep.solver.executors.HeldChunks`), or sent to
        the workers of ``dask_client`` once and kept there for every prior (:meth:`resident`)."""
        if not self.blocks:
            raise ValueError("no star with a transit to solve")
        shares = 1 if dask_client is not None else max(1, int(workers))
        n_blocks = len(self.blocks)
        ranges = solver_chunks(n_blocks, self.blocks[0].n, self.n_measurements, self.spline.n_coef, chunk_stars,
                               shares)
        border = None if self.calibration is None else calibration_design(self.calibration)
        if dask_client is not None:
            held = self.resident(dask_client, ranges)
        else:
            held = HeldChunks([self.chunk(lo, hi, border) for lo, hi in ranges], shares,
                              [share_of(lo, n_blocks, shares) for lo, _ in ranges])
        return SolverChunks(ranges, held, border, None if border is None else self.h)

    def chunk(self, lo: int, hi: int, border=None) -> tuple:
        """The solver's chunk of blocks ``lo .. hi - 1``: ``(blocks, measurements, stars' arrays)``
        as :func:`~.blocks.build_chunk` makes it (with ``border``, each block's rows of it)."""
        blocks = self.blocks[lo:hi]
        v = slice(blocks[0].first, blocks[-1].first + blocks[-1].n)
        s = self.solved[v]
        kept = {"normals": self.normals[v], "x_true": self.x_true[v], "star": s,
                **{c: self.stars[c].to_numpy()[s] for c in ("l", "b", "phot_g_mean_mag")},
                "mean_tcb_jd": self.mean_tcb_jd[v]}
        if border is not None:
            kept["border"] = [np.ascontiguousarray(border[b.rows]) for b in blocks]
        return blocks, [self.h[b.rows] for b in blocks], kept

    def resident(self, client, ranges):
        """The solver's chunks (blocks ``ranges``, their measurements and stars' arrays) sent
        once to the workers of a Dask ``client`` and kept there for every prior's solution
        (only a prior's label is sent with it, :func:`~.chunk_tasks.attach_prior`)."""
        from ...solver.dask_resident import DaskChunks

        key = tuple(map(tuple, ranges))  # with the client itself: a closed one's id may be reused
        if self.sent is None or self.sent[0][0] is not client or self.sent[0][1] != key:
            chunks = [self.chunk(lo, hi) for lo, hi in ranges]
            self.sent = ((client, key), DaskChunks.scatter(client, [c[:2] for c in chunks]).attached(
                with_stars, [c[2] for c in chunks]))
        return self.sent[1]

    def star_columns(self, rows: slice) -> tuple[dict, int]:
        st = self.stars
        lo, hi = np.searchsorted(self.solved, [rows.start, rows.stop])
        solved = np.zeros(rows.stop - rows.start, dtype=bool)
        solved[self.solved[lo:hi] - rows.start] = True
        cols = {c: st[c].to_numpy()[rows] for c in ("class_key", "n_fov", "n_fov_scheduled", "span_days")}
        return {**cols, "solved": solved}, int(lo)


class InProcess:
    """The table of stars in this process as one partition, with its transits (sorted by
    star): :class:`~.preparation.Partitions` whose tasks are called at once (a handle is the
    value itself) and whose chunks are built block by block into :class:`LocalData`."""

    def __init__(self, stars: pd.DataFrame, transits: dict):
        self.stars, self.found = stars, transits
        self.first = np.zeros(1, dtype=np.int64)
        self.sizes = np.array([len(stars)], dtype=np.int64)
        self.settings = self.summarised = self.kept = None

    def open(self, settings: PrimarySettings, dead, min_fov: int) -> None:
        self.settings = settings
        self.summarised = partition_summary(self.found, dead, 0, len(self.stars), min_fov)

    def table(self, p: int):
        return self.stars

    def summary(self, p: int):
        return self.summarised

    def transits(self, p: int):
        return self.found

    def submit(self, fn, *args):
        return fn(*args)

    def gather(self, handles) -> list:
        return list(handles)

    def shared(self, name: str, obj):
        return obj

    def epochs(self, handles, start_jd: float, end_jd: float):
        return np.concatenate(handles)

    def build(self, layout: Layout, settings: PrimarySettings, spline, truth: tuple, dead) -> Built:
        """One block at a time (its partials exist twice only while it is built), its
        measurements written in place; the attitude band summed over the blocks in the fixed
        tree (as where chunks are built on a cluster: the same bits)."""
        n, harmonics = layout.n_solved, settings.basic_angle_harmonics
        h, normals, x_true = np.empty(layout.n_rows), np.empty((n, 5, 5)), np.empty((n, 5))
        cal = (np.zeros(layout.n_rows), np.zeros(layout.n_rows)) if harmonics else None
        blocks, infos = [], []
        inputs = (self.stars, self.summarised, self.found)
        for k in range(layout.n_blocks):
            spec, _ = layout.chunk(k, k + 1, band=False)
            (got, hs, kept), info = build_chunk(spec, settings, spline, truth, dead, *inputs)
            stars = slice(k * layout.block_stars, k * layout.block_stars + layout.stars_of(k))
            normals[stars], x_true[stars] = kept["normals"], kept["x_true"]
            for blk, hb, c in zip(got, hs, kept.get("calibration", [None] * len(got))):
                h[blk.rows] = hb
                if c is not None:
                    cal[0][blk.rows], cal[1][blk.rows] = c.omega, c.weight
            blocks += got
            infos.append(info)
        mask = np.zeros(spline.n_coef, dtype=bool)
        for info in infos:
            mask[info["covered"]] = True
        self.kept = dict(normals=normals, h=h, x_true=x_true,
                         calibration=None if cal is None else BasicAngleColumns(omega=cal[0], weight=cal[1],
                                                                                harmonics=harmonics))
        return Built(blocks=blocks, covered=mask, naa_band=pairwise_sum(att_band(b) for b in blocks))

    def data(self, **common) -> LocalData:
        solved = np.flatnonzero(self.summarised["solved"])
        return LocalData(stars=with_transit_columns(self.settings, self.stars, self.summarised), solved=solved,
                         mean_tcb_jd=self.summarised["mean_tcb_jd"][solved], **self.kept, **common)


def prepare(settings: PrimarySettings, stars: pd.DataFrame, transits: dict, *,
            with_noise: bool = True, block_stars: int = SOLVER_BLOCK_STARS) -> LocalData:
    """:func:`~.preparation.prepare_data` of the table ``stars`` in this process, with its
    ``transits`` sorted by star (as :func:`~.transits.transits_of` gives them; their fields
    of view are needed with ``basic_angle_harmonics``). The solver's blocks are built block by
    block of ``block_stars`` stars (a property of the problem, as in
    :class:`~mcsweep.solver.GlobalProblem`). ``with_noise=False`` leaves the measurement
    noise out (tests)."""
    if settings.basic_angle_harmonics and transits.get("following") is None:
        raise ValueError("the basic-angle calibration needs each transit's field of view: transits from "
                         "transits_of (star_transits with with_fov=True)")
    star = transits["star"]
    if star.size and np.any(np.diff(star) < 0):
        raise ValueError("transits must be sorted by star")
    return prepare_data(settings, InProcess(stars, transits), block_stars=block_stars, with_noise=with_noise)
