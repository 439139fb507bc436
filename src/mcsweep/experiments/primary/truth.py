"""The truth of the primary experiment and the solver's attitude model (paper Sect. 4.2).

The data set's dead time, the true attitude (the scanning law plus a smooth random rotation,
:mod:`~.experiment` notes, step 3), the stars' true parameters and the solver's attitude
spline (Lindegren et al. 2012, Sect. 3.3): made once per run, the same wherever the
measurements are built (:mod:`~.preparation`).
"""

from __future__ import annotations

import numpy as np

from ...astrometry.design import JULIAN_YEAR_DAYS
from ...scanning.timeline import DeadTime
from ...solver import AttitudeSpline
from ...solver.attitude_spline import sorted_epochs
from ..global_solution.classes import dead_time
from .experiment import ATTITUDE_STREAM, DEAD_STREAM, PrimarySettings, stream_seed

__all__ = ["dead_time_of", "true_attitude", "rotation_at", "block_epochs", "true_parameters",
           "solver_knot_interval_days", "attitude_spline"]


def dead_time_of(settings: PrimarySettings) -> DeadTime:
    """The data set's dead time (one draw, its own stream)."""
    return dead_time(stream_seed(settings.seed, DEAD_STREAM), settings.start_jd, settings.end_jd,
                     settings.dead_time_fraction, outage_days=settings.dead_time_outage_days)


def true_attitude(settings: PrimarySettings) -> tuple[AttitudeSpline, np.ndarray]:
    """The smooth random rotation (:mod:`~.experiment` notes, step 3): its spline and coefficients [mas]."""
    rng = np.random.default_rng(stream_seed(settings.seed, ATTITUDE_STREAM))
    timescale_days = settings.attitude_timescale_days
    shift_days = rng.uniform(0.0, timescale_days)  # knots off the solver's grid
    spline = AttitudeSpline(settings.start_jd - shift_days, settings.end_jd + timescale_days, timescale_days)
    return spline, rng.normal(0.0, settings.attitude_amplitude_mas, (spline.n_coef, 3))


def rotation_at(true_attitude: tuple, tcb_jd) -> np.ndarray:
    """A (spline, coefficients) rotation at ``tcb_jd`` [mas], (m, 3)."""
    spline, coef = true_attitude
    return spline.evaluate(coef, tcb_jd)


def block_epochs(t_ref_jd: float, block) -> np.ndarray:
    """TCB JD of a block's measurements, from the epochs the block stores (to ~1e-14 d)."""
    return t_ref_jd + JULIAN_YEAR_DAYS * block.t


def true_parameters(stars, solved) -> np.ndarray:
    """The truth of the solved stars (n, 5): position zero at the reference epoch (the offsets
    are what is solved for), the population's parallax and proper motion. ``stars``: a table
    or a mapping of its columns; ``solved``: indices or a slice."""
    plx = np.asarray(stars["parallax"])[solved]
    zero = np.zeros(plx.size)
    return np.column_stack([zero, zero, plx, np.asarray(stars["pmra"])[solved], np.asarray(stars["pmdec"])[solved]])


def solver_knot_interval_days(settings: PrimarySettings, n_fov_transits: int, dead: DeadTime) -> float:
    """The solver's knot interval [day]: the configured one (``settings.knot_interval_days``,
    from ``experiment.primary.knot_interval_hours``), or with ``knot_transits`` the
    mean live time per ``knot_transits`` FoV transits (the density of AGIS's 30 s knots at the
    paper's 1.5e6 stars: ~25 per knot; Lindegren et al. 2016, A&A 595, A4, Fig. D.4); the
    knots themselves are then placed by the data (:class:`~mcsweep.solver.AttitudeSpline`)."""
    if settings.knot_transits is None:
        return settings.knot_interval_days
    live_days = (settings.end_jd - settings.start_jd) - dead.total_days
    return live_days * settings.knot_transits / max(int(n_fov_transits), 1)


def attitude_spline(settings: PrimarySettings, dead: DeadTime, epochs=None) -> AttitudeSpline:
    """The solver's spline: segments between the gaps, as AGIS; with ``knot_transits`` its knots
    placed by ``epochs``, the solution's live FoV transits (not needed otherwise): an array,
    or an object answering :class:`~mcsweep.solver.attitude_spline.SortedEpochs`' questions
    (the epochs on a cluster's workers, :class:`~.knots.ClusterEpochs`)."""
    gaps = (dead.starts, dead.stops)
    if settings.knot_transits is None:
        return AttitudeSpline(settings.start_jd, settings.end_jd, settings.knot_interval_days, gaps=gaps)
    epochs = sorted_epochs(epochs)
    return AttitudeSpline(settings.start_jd, settings.end_jd, solver_knot_interval_days(settings, epochs.size, dead),
                          gaps=gaps, epochs=epochs, transits_per_knot=settings.knot_transits, knot_rule=settings.knot_rule)
