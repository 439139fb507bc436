"""The primary solution's data held in this process, and its solutions here or on forked workers.

:class:`InProcess` runs :func:`~.preparation.prepare_data` in this process: the whole table is
one partition (its transits searched beforehand, in chunks through the run's executor,
:func:`~.transits.transits_of`), every task is called at once, and the chunks are built one
block at a time, their measurements written into one array (memory flat: a block's
temporaries at a time). :class:`LocalData` holds every star's arrays and solves a prior with
:func:`mcsweep.solver.solve_global` in this process, on forked workers, or on a Dask
cluster to which its chunks are sent once (:meth:`LocalData.resident`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ...astrometry.solve import prior_diagonal
from ...solver import SOLVER_BLOCK_STARS, GlobalProblem, solve_global
from ...solver.calibration import BasicAngleColumns, calibration_design
from ...solver.reduction import pairwise_sum
from .blocks import build_chunk
from .data import PreparedData
from .evaluation import block_attitude_sq, evaluate_solution
from .experiment import PrimarySettings, prior_sigmas
from .preparation import Built, Layout, prepare_data
from .results import StarParts, solved_results
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
    calibration: BasicAngleColumns | None = None  # the basic-angle variation's design, problem order
    cached_problem: GlobalProblem | None = dataclasses.field(default=None, repr=False)
    sent: tuple | None = dataclasses.field(default=None, repr=False)  # ((client, ranges), DaskChunks)

    def border_names(self) -> list | None:
        return None if self.calibration is None else self.calibration.names()

    def problem(self, prior_diagonal) -> GlobalProblem:
        """The global problem under ``prior_diagonal``: assembled once from the blocks, then
        only the per-star inverses and frame weights change from prior to prior
        (:meth:`GlobalProblem.with_prior`, bit-identical to a new problem). Only the latest
        prior's inverses are kept (0.3 GB at 1.5e6 stars)."""
        if self.cached_problem is None:
            st = self.stars
            self.cached_problem = GlobalProblem.from_blocks(
                self.blocks, self.normals, prior_diagonal, st["ra"].to_numpy()[self.solved],
                st["dec"].to_numpy()[self.solved], n_coef=self.spline.n_coef, n_measurements=self.n_measurements,
                naa_band=self.naa_band)
        else:
            self.cached_problem = self.cached_problem.with_prior(prior_diagonal)
        return self.cached_problem

    def resident(self, client, ranges):
        """The solver's chunks (blocks ``ranges``, their measurements) sent once to the workers
        of a Dask ``client`` and kept there for every prior's solution (only the per-star
        inverses of a prior are sent with it,
        :meth:`~mcsweep.solver.dask_resident.DaskChunks.with_inverses`)."""
        from ...solver.dask_resident import DaskChunks

        key = tuple(map(tuple, ranges))  # with the client itself: a closed one's id may be reused
        if self.sent is None or self.sent[0][0] is not client or self.sent[0][1] != key:
            self.sent = ((client, key), DaskChunks.scatter(
                client, [(self.blocks[lo:hi], [self.h[b.rows] for b in self.blocks[lo:hi]]) for lo, hi in ranges]))
        return self.sent[1]

    def attitude_sq(self, coef, eps, omega) -> np.ndarray:
        """Sum over the measurements of the squared attitude error (3,) [mas^2], block by block
        in the fixed tree (:func:`~.evaluation.block_attitude_sq`)."""
        total = pairwise_sum(block_attitude_sq(b, coef, eps, omega, self.true_attitude, self.t_ref_jd)
                             for b in self.blocks)
        return np.zeros(3) if total is None else total

    def solve(self, settings: PrimarySettings, label: str, *, log=None, chunk_stars=None, workers: int = 1,
              dask_client=None, attitude_start=None, equal: bool = False) -> tuple:
        """One global solution of the data held here (``dask_client``: the measurements' chunks
        kept on its workers from prior to prior; ``workers``: forked workers)."""
        st, s = self.stars, self.solved
        sig = prior_sigmas(settings, label, st["l"].to_numpy()[s], st["b"].to_numpy()[s],
                           st["phot_g_mean_mag"].to_numpy()[s])
        tau_yr = st["epoch_offset_yr"].to_numpy()[s] if settings.evaluation_epoch == "star_mean" else None
        # Raises if a star's block is singular: every solved star has >= 1 AL+AC or 2 AL
        # measurements, so it cannot be under a positive prior.
        problem = self.problem(prior_diagonal(sig, settings.ratio_R))
        resident = None
        if dask_client is not None:
            ranges = problem.chunks(chunk_stars)
            stars = [slice(self.blocks[lo].first, self.blocks[hi - 1].first + self.blocks[hi - 1].n)
                     for lo, hi in ranges]
            resident = self.resident(dask_client, ranges).with_inverses([problem.src_inv[sl] for sl in stars])
        # the basic-angle calibration's unknowns border the system (mcsweep.solver.calibration)
        sol = solve_global(problem, self.h, **settings.criterion, log=log, chunk_stars=chunk_stars,
                           residuals=False, workers=workers, resident_chunks=resident,
                           border=None if self.calibration is None else calibration_design(self.calibration),
                           attitude_start=attitude_start)
        eps, omega, outcome = evaluate_solution(
            problem.K, sol.cov, sol.x - self.x_true, [slice(b.first, b.first + b.n) for b in self.blocks],
            equal=equal, tau_yr=tau_yr, confidence=settings.confidence)
        sq = self.attitude_sq(sol.attitude, eps, omega)
        results = StarParts.of_frame(solved_results(0, st["class_key"].to_numpy(), st["n_fov"].to_numpy(),
                                                    st["n_fov_scheduled"].to_numpy(), st["span_days"].to_numpy(),
                                                    s, (*outcome, sig)))
        return sol, resident, eps, omega, results, sq


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
        measurements written in place; the attitude band is left to the problem."""
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
        return Built(blocks=blocks, covered=mask, naa_band=None)

    def data(self, **common) -> LocalData:
        return LocalData(stars=with_transit_columns(self.settings, self.stars, self.summarised),
                         solved=np.flatnonzero(self.summarised["solved"]), **self.kept, **common)


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
