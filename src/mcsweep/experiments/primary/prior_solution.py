"""One global solution of the primary experiment (paper Sect. 4.2, Table 3) for one prior,
wherever its data live: held in this process (:class:`~.local.LocalData`) or on a Dask
cluster's workers (:class:`~.cluster.ClusterData`), each solving through
:meth:`~.data.PreparedData.solve`; both give the same bits, and the summary is made here
once for both."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
import pandas as pd

from ...solver.tasks import back_task, direction_task, forward_task
from .data import PreparedData
from .evaluation import attitude_error_series
from .experiment import PrimarySettings
from .results import StarParts

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
    # astrometry sets the removed rotation (docs/table3.md, the candidate for the paper's
    # collapse); not the default.
    equal = settings.frame_fit != "precision"
    sol, resident, eps, omega, results, sq = data.solve(
        settings, label, log=log, chunk_stars=chunk_stars, workers=workers, dask_client=dask_client,
        attitude_start=attitude_start, equal=equal)
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
    if resident is not None and sol.history:  # what travelled per iteration, measured:
        # the iterations' passes only (the one-off setup and residual passes apart)
        sent, received = resident.bytes_per_call(forward_task, back_task, direction_task)
        extra["dask_mib_per_iteration"] = [sent / len(sol.history) / 2**20, received / len(sol.history) / 2**20]
    return PriorSolution(results, hist, extra, attitude_error_series(data, sol.attitude, eps, omega), sol.attitude)
