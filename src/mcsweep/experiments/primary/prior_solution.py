"""One global solution of the primary experiment (paper Sect. 4.2, Table 3) for one prior,
wherever its data live: held in this process (:class:`~.local.LocalData`) or on a Dask
cluster's workers (:class:`~.cluster.ClusterData`).

One sequence for both (:func:`solve_prior`): the data give the solver's chunks
(:meth:`~.data.PreparedData.solver_chunks`: held here, :class:`~mcsweep.solver.executors.HeldChunks`,
solved in process or on forked workers; or kept on a cluster,
:class:`~mcsweep.solver.dask_resident.DaskChunks`); the prior is attached to each chunk where
it is (its stars' prior sigmas, inverses and frame weights, :func:`~.chunk_tasks.attach_prior`),
the frame penalty's medians found by selection, the problem
(:class:`~mcsweep.solver.problem.ResidentProblem`) solved with the stars' solution left in
the chunks, the frame rotator fitted and each star's outcome made there
(:mod:`~.chunk_tasks`), and the per-star results assembled part by part from the data's
star columns (:meth:`~.data.PreparedData.star_columns`) and the chunks' outcomes. A worker
lost at any pass restarts the sequence on the rebuilt chunks (the same bits); lost while
the parts are read, the prior is solved again.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
import pandas as pd

from ...solver import solve_global
from ...solver.executors import ChunksLost, chunk_values, retried
from ...solver.frame import frame_from_sums, penalty_weights
from ...solver.problem import ResidentProblem
from ...solver.reduction import pairwise_sum, run_level
from ...solver.selection import median
from ...solver.tasks import back_task, direction_task, forward_task
from .chunk_tasks import attach_prior, attitude_sq_task, fit_task, outcome_slice, outcome_task, prior_task, weight_digits
from .data import PreparedData
from .evaluation import attitude_error_series
from .experiment import PrimarySettings
from .results import StarParts, solved_results

__all__ = ["PriorSolution", "solve_prior"]


class PriorSolution(NamedTuple):
    """What :func:`solve_prior` gives: per-star results (:class:`~.results.StarParts`,
    read part by part), PCG history, summary (``extra``),
    attitude error on a grid, and the attitude spline coefficients solved (``n_coef, 3``,
    mas), from which the next prior's solution may start (``solver_start='previous'``)."""

    results: StarParts
    history: pd.DataFrame
    extra: dict
    attitude_error: pd.DataFrame
    attitude: np.ndarray


def solve_prior(settings: PrimarySettings, data: PreparedData, label: str, log=None, *,
                chunk_stars=None, workers: int = 1, dask_client=None, attitude_start=None) -> PriorSolution:
    """One global solution for the prior ``label`` (:class:`PriorSolution`).

    Per-star results (all stars of the solution's table, part by part:
    :class:`~.results.StarParts`): ``inside`` (1/0, -1 not solved),
    ``err_mas`` (position error after the frame correction), ``err_parallax_mas``
    (estimated - true parallax), ``sigma_prior_mas``. ``extra``: iterations, convergence,
    attitude error RMS per axis [uas] over the measurement epochs, fitted frame rotation and
    spin; ``attitude_error`` on a grid (:func:`~.evaluation.attitude_error_series`).
    ``chunk_stars``, ``workers``, ``dask_client``: the chunk size, forked workers or Dask
    cluster (whose workers keep the chunks and their star vectors) for the solver's per-chunk
    work (:func:`mcsweep.solver.solve_global`); results do not depend on them.
    ``attitude_start``: attitude coefficients PCG starts from (None: zero corrections to the
    scanning law); any start gives the least-squares solution to ``solver_error_tol``, a good
    one in fewer iterations (:func:`~mcsweep.solver.solve_global`).
    """
    # frame_fit='equal' weights every star alike: then the faint stars' prior-biased
    # astrometry sets the removed rotation (docs/notes/table3/looking_for_the_collapse.md, the candidate for the paper's
    # collapse); not the default.
    equal = settings.frame_fit != "precision"
    chunks = data.solver_chunks(chunk_stars=chunk_stars, workers=workers, dask_client=dask_client)
    sol, resident, eps, omega, results, sq = _solve_chunks(settings, data, label, chunks, chunk_stars=chunk_stars,
                                                           log=log, equal=equal, attitude_start=attitude_start)
    m = data.n_measurements
    hist = pd.DataFrame([dataclasses.asdict(r) for r in sol.history])
    hist.insert(0, "prior", label)
    extra = {"converged": bool(sol.converged), "iterations": len(sol.history),
             "attitude_rms_uas": (1e3 * np.sqrt(sq / m)).tolist() if m else [],
             "frame_rotation_mas": eps.tolist(), "frame_spin_mas_yr": omega.tolist(),
             "residual_rms": sol.residual_rms,
             "seconds": float(sol.history[-1].seconds) if sol.history else 0.0}
    names = data.border_names()
    if names is not None:
        extra["basic_angle_mas"] = dict(zip(names, sol.border.tolist()))
    if hasattr(resident, "bytes_per_call") and sol.history:  # what travelled per iteration, measured:
        # the iterations' passes only (the one-off setup and residual passes apart)
        sent, received = resident.bytes_per_call(forward_task, back_task, direction_task)
        extra["dask_mib_per_iteration"] = [sent / len(sol.history) / 2**20, received / len(sol.history) / 2**20]
    return PriorSolution(results, hist, extra, attitude_error_series(data, sol.attitude, eps, omega), sol.attitude)


def _is_chunks_lost(exc: BaseException) -> bool:
    return isinstance(exc, ChunksLost)


def _solve_chunks(settings: PrimarySettings, data: PreparedData, label: str, chunks, *, chunk_stars, log,
                  equal: bool, attitude_start) -> tuple:
    """The prior ``label`` attached to the solver's ``chunks``
    (:class:`~.data.SolverChunks`), solved and evaluated there (module notes). Returns
    (solution, the prior's chunks, eps, omega, StarParts, summed squared attitude error (3,) [mas^2])."""

    def solve():
        resident = chunks.chunks.attached(attach_prior, [(settings, label)] * len(chunks.ranges))
        return (resident, *retried(lambda: _solve_once(settings, data, resident, chunks, chunk_stars=chunk_stars,
                                                       log=log, equal=equal, attitude_start=attitude_start),
                                   _is_chunks_lost))

    state = {"solution": solve()}

    def resolve():  # the stars' outcome went with a worker: solved again, same bits
        state["solution"] = solve()

    def make(rows: slice) -> pd.DataFrame:
        return retried(lambda: _part(data, state["solution"][0], chunks.ranges, rows), _is_chunks_lost, resolve)

    resident, sol, eps, omega, sq = state["solution"]
    return sol, resident, eps, omega, StarParts(data.n_stars, make), sq


def _solve_once(settings: PrimarySettings, data: PreparedData, resident, chunks, *, chunk_stars, log, equal,
                attitude_start) -> tuple:
    """One pass of the sequence on the prior's chunks ``resident``: (solution, eps, omega, sq)."""
    ranges = chunks.ranges
    n_chunks = len(ranges)
    levels = [run_level(lo, hi) for lo, hi in ranges]
    got = chunk_values(resident.run, prior_task, [(ci,) for ci in range(n_chunks)])
    bad = sum(g[0] for g in got)
    if bad:  # every solved star has >= 1 AL+AC or 2 AL measurements: not under a positive prior
        raise ValueError(f"{bad} stars have singular source blocks; remove them first")
    n = data.n_solved

    def counts_of(which: int):
        return lambda queries: chunk_values(resident.run, weight_digits,
                                            [(ci, [(which, q) for q in queries]) for ci in range(n_chunks)])

    # the medians by selection, not by gathering every star's weights (mcsweep.solver.selection)
    w_pos, w_pm = penalty_weights(median(counts_of(0), n), median(counts_of(1), n), n)
    problem = ResidentProblem(data.blocks, n_coef=data.spline.n_coef, n_measurements=data.n_measurements,
                              naa_band=data.naa_band, frame_means=pairwise_sum((g[1] for g in got), None, levels) / n,
                              w_pos=w_pos, w_pm=w_pm)
    del got
    # the basic-angle calibration's unknowns border the system (mcsweep.solver.calibration)
    sol = solve_global(problem, chunks.h, **settings.criterion, log=log, chunk_stars=chunk_stars, residuals=False,
                       resident_chunks=resident, border=chunks.border, attitude_start=attitude_start)
    eps, omega = frame_from_sums(pairwise_sum(
        chunk_values(resident.run, fit_task, [(ci, equal) for ci in range(n_chunks)]), None, levels))
    chunk_values(resident.run, outcome_task, [(ci, eps, omega, settings.confidence) for ci in range(n_chunks)])
    sq = pairwise_sum(chunk_values(resident.run, attitude_sq_task,
                                   [(ci, sol.attitude, eps, omega, data.true_attitude, data.t_ref_jd)
                                    for ci in range(n_chunks)]), None, levels)
    return sol, eps, omega, np.zeros(3) if sq is None else sq


def _part(data: PreparedData, resident, ranges, rows: slice) -> pd.DataFrame:
    """Part ``rows`` of a solution's per-star results: the data's star columns and the
    outcomes of the chunks holding its solved stars."""
    cols, lo = data.star_columns(rows)
    solved = cols.pop("solved")
    hi = lo + int(np.count_nonzero(solved))
    outcome = ()
    if hi > lo:
        spans = data.blocks
        firsts = np.array([spans[a].first for a, _ in ranges])
        lasts = np.array([spans[b - 1].first + spans[b - 1].n for _, b in ranges])
        cis = np.flatnonzero((firsts < hi) & (lasts > lo))
        out = chunk_values(resident.run, outcome_slice, [(int(ci), lo, hi) for ci in cis])
        outcome = tuple(np.concatenate([o[i] for o in out]) for i in range(4))
    return solved_results(rows.start, cols["class_key"], cols["n_fov"], cols["n_fov_scheduled"], cols["span_days"],
                          solved, outcome)
