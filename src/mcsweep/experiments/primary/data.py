"""What every prior's primary solution shares, wherever its stars and measurements are.

:class:`PreparedData` holds what the driver keeps of the prepared data in every case: the
dead time, the true attitude, the solver's spline, the blocks' places in the problem, which
coefficients have data, and the counts of stars and measurements. Where the stars and
measurements themselves are is a subclass's: held in this process
(:class:`~.local.LocalData`) or kept on a Dask cluster's workers
(:class:`~.cluster.ClusterData`). Each gives the solver's chunks where they are
(:meth:`PreparedData.solver_chunks`, a :class:`SolverChunks`) and its star columns
(:meth:`PreparedData.star_columns`); one sequence solves a prior on them, whichever they are
(:func:`~.prior_solution.solve_prior`), so both give the same bits.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from ...scanning.timeline import DeadTime
from ...solver import AttitudeSpline
from ...solver.attitude_spline import DEGREE
from .truth import block_epochs, rotation_at

__all__ = ["PreparedData", "SolverChunks"]


class SolverChunks(NamedTuple):
    """The solver's chunks of prepared data where they are: ``ranges`` (each chunk's blocks,
    :func:`~mcsweep.solver.problem.solver_chunks`), ``chunks`` (the chunks ``(blocks,
    measurements, stars' arrays)`` with the resident chunks' protocol: held here,
    :class:`~mcsweep.solver.executors.HeldChunks`, or on a cluster,
    :class:`~mcsweep.solver.dask_resident.DaskChunks`), and with a calibration its design
    ``border (m, k)`` and the measurements ``h`` (:func:`~mcsweep.solver.solve_global`), else None."""

    ranges: list
    chunks: object
    border: np.ndarray | None = None
    h: np.ndarray | None = None


@dataclasses.dataclass(kw_only=True)
class PreparedData:
    """Stars, observations and noisy measurements shared by every prior's solution: what the
    driver holds of them wherever they are (module notes)."""

    blocks: list             # the solver's blocks of the solved stars (StarBlocks, or BlockSpans of blocks elsewhere)
    spline: AttitudeSpline
    true_attitude: tuple     # (AttitudeSpline, coefficients (n, 3) [mas]): the true rotation
    t_ref_jd: float
    dead: DeadTime
    covered: np.ndarray      # (n_coef,) bool: spline coefficients with a measurement in their support
    n_rows: int              # measurements
    n_stars: int             # stars of the solution's table (solved or not)
    n_solved: int            # stars in the solution (with enough live transits)
    n_fov_transits: int      # live FoV transits of the solved stars (the data of the attitude)
    naa_band: np.ndarray | None = None  # the attitude block's band if summed where the blocks were built

    #: Whether the blocks and measurements live on a cluster's workers.
    on_cluster = False

    @property
    def dead_days(self) -> float:
        return self.dead.total_days

    @property
    def n_measurements(self) -> int:
        return int(self.n_rows)

    def coefficients_with_data(self) -> int:
        """Spline coefficients (per axis) with at least one measurement in their support: all
        of them when the spline is broken at the gaps; the solver holds others at zero."""
        return int(self.covered.sum())

    @property
    def n_knot_intervals(self) -> int:
        return self.spline.n_coef - DEGREE * self.spline.n_segments

    @property
    def transits_per_knot(self) -> float:
        """Realised mean number of FoV transits per knot interval (``knot_transits``)."""
        return self.n_fov_transits / max(self.n_knot_intervals, 1)

    @property
    def mean_knot_interval_hours(self) -> float:
        """Realised mean knot interval over the live time [h] (the configured one is
        ``experiment.primary.knot_interval_hours``, or none with ``knot_transits``)."""
        live = float(np.sum(self.spline.segments[:, 1] - self.spline.segments[:, 0]))
        return 24.0 * live / max(self.n_knot_intervals, 1)

    def block_epochs(self, block) -> np.ndarray:
        """TCB JD of a block's measurements (:func:`~.truth.block_epochs`)."""
        return block_epochs(self.t_ref_jd, block)

    def epochs(self) -> np.ndarray:
        """TCB JD of every measurement, in the problem's order."""
        return np.concatenate([self.block_epochs(b) for b in self.blocks]) if self.blocks else np.zeros(0)

    def true_attitude_at(self, tcb_jd) -> np.ndarray:
        """The true rotation (:mod:`~.experiment` notes, step 3) at ``tcb_jd`` [mas], (m, 3)."""
        return rotation_at(self.true_attitude, tcb_jd)

    def border_names(self) -> list | None:
        """Names of the calibration unknowns solved with the stars and attitude, or None."""
        return None

    def solver_chunks(self, *, chunk_stars, workers: int, dask_client) -> SolverChunks:
        """The solver's chunks of ``chunk_stars`` stars (None: as long as they go), solved on
        ``workers`` forked workers or on the Dask cluster of ``dask_client`` (arguments as
        :func:`~.prior_solution.solve_prior`)."""
        raise NotImplementedError

    def star_columns(self, rows: slice) -> tuple[dict, int]:
        """The results' columns of stars ``rows`` of the table (``class_key``, ``n_fov``,
        ``n_fov_scheduled``, ``span_days``, and ``solved``, a mask) and the index among the
        solved stars of the first solved one."""
        raise NotImplementedError
