"""One-year global (primary) solution with the attitude from the same data (paper Sect. 4.2, Table 3):
the procedure, its settings and its random streams.

The attitude is now *not* known: stars and attitude are solved together
(:mod:`mcsweep.solver`, AGIS-style PCG). Procedure, following Sect. 4.2 (made by
:mod:`~.preparation` with :mod:`~.truth`, :mod:`~.transits` and :mod:`~.blocks`, evaluated by
:mod:`~.evaluation`):

1. *Stars.* The three classes of Table 2 (the ``class_size`` brightest stars fainter
   than G0 = 11, 15, 19 over the whole sky, drawn exactly as in the secondary
   experiment, :mod:`mcsweep.experiments.global_solution.classes`), and only
   those: the paper's global solution holds these 1.5e6 stars (Sect. 4: 5e5 per class)
   and determines the attitude from them, all with the prior. ``extra_sources`` (default
   0) adds that many extra stars (the brightest fainter than ``extra_g_min``) to the
   solution, an option *not* in the paper: well-observed extra stars add attitude
   information the paper's solution did not have (docs/notes/table3/looking_for_the_collapse.md). The default is reduced
   (``class_size`` in conf/experiment/primary.yaml) so a run takes minutes on 2 cores.
2. *Observations.* FoV transits of the configured scanning law (default the flown NSL)
   over ``mission_years`` (1) from ``mission_start`` (start of routine operations,
   2014-07-25; Prusti et al. 2016), 20 % dead time as blocks of the time line
   (:func:`mcsweep.experiments.global_solution.classes.dead_time`; paper Sect. 4.2), one AL
   measurement per FoV transit and one AC measurement where the noise config uses AC,
   with the uncertainties of :class:`~mcsweep.astrometry.noise.NoiseModel`.
3. *True attitude.* The scanning law plus a smooth random rotation about all three axes:
   a cubic spline with knot interval ``experiment.primary.attitude_timescale_hours`` whose knots are
   shifted by a random fraction of an interval (so it is *not* inside the solver's spline
   space), coefficients ``N(0, attitude_amplitude_mas^2)`` per axis. Only the part the
   solver's spline cannot follow matters (the model is linear in the small correction:
   a constant or a slowly varying rotation is absorbed exactly), so the amplitude is not
   critical. The default, 10 mas on a 24 h time scale (8 default knot intervals), is a
   choice, not a published figure (no published spectrum of Gaia's attitude
   perturbations on hour-to-day scales was found; docs/notes/table3/true_attitude.md): it is smooth on the
   knot scale as Gaia's attitude is on its tens-of-seconds knots, and the unmodelled part
   stays below the noise (measured: 100 mas instead of 10 leaves the attitude error
   unchanged to the 0.1 uas printed, docs/notes/table3/true_attitude.md). A time scale close to the knot
   interval leaves mas-level unmodelled attitude (measured: 3-4 mas RMS with 6 h against
   12 h knots), which then dominates every error; the sensitivity is a config value
   away. The solution starts from the scanning law (as AGIS starts from the commanded attitude).
4. *Solution.* Unknowns: five astrometric parameters per star at one reference epoch
   (:func:`~mcsweep.experiments.global_solution.epoch.resolve_reference_epoch`, default the mid-point
   of the data set, Sect. 2.1) with the prior of Eq. 18 (same prior rule for every
   star, extra stars included), and cubic-spline attitude corrections (Lindegren et al.
   2012, Sect. 3.3) with ``experiment.primary.knot_interval_hours``. No instrument calibration (none is
   simulated). Frame: zero mean rotation and spin of the corrections over all sources
   (:mod:`mcsweep.solver.frame`). One PCG solution per prior of ``priors``
   (``'<k>F90'`` = k sigma_F90, ``'<s>mas'`` = a fixed sigma,
   :mod:`mcsweep.experiments.global_solution.priors`; default the rows of Table 3: F90, 10F90,
   1000mas).
5. *Evaluation.* As the frame rotator: the rotation and spin fitted to (estimated -
   true) over all sources are removed; each star's formal covariance is its own block
   ``(N_ss + N_p)^-1`` with the attitude taken as known (as AGIS gives it). Per star:
   inside the P ellipse, position error at the reference epoch.

Knot interval: AGIS uses intervals of tens of seconds for ~1e8 primaries (Lindegren et
al. 2012, Sect. 3.3), i.e. of order 1e3 observations per knot and axis; the paper does not
give AGISLab's. Our reduced default (3 x 30000 stars, ~14 transits each per year, AL + AC)
gives ~140 FoV transits per hour, so 3 h keeps ~420 transits per knot; at full scale
(1.5e6 stars) 0.18 h gives the same. The attitude's noise scales as 1/sqrt(stars x knot
interval), the attitude error the prior's bias causes does not (docs/notes/table3/reproduction.md).

Reproducibility: SeedSequence(seed, spawn_key=(42, stream, ...)): population of a class
(stream 0, class key round(100 G0); the extra stars key 0), dead time (1), true attitude (2),
measurement noise (3, key: the block of ``SOLVER_BLOCK_STARS`` solved stars, drawn in the block's
order). So results do not depend on n_jobs, chunking or where a block is built (the driver,
or a Dask worker: :mod:`~mcsweep.experiments.primary.preparation`); the transit search is
chunked over stars and re-assembled in star order. (Before the stars were kept on the
workers the noise was one stream over all blocks: the same statistics, other draws.)
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...astrometry.design import JULIAN_YEAR_DAYS
from ...astrometry.noise import G_MAX
from ...errors import UserInputError
from ..global_solution.priors import parse_prior, prior_sigma_mas
from ..global_solution.settings import GlobalSettings, global_fields, spawn

__all__ = [
    "EXTRA_KEY",
    "TAG",
    "DEAD_STREAM",
    "ATTITUDE_STREAM",
    "NOISE_STREAM",
    "FACTOR_STREAM",
    "PrimarySettings",
    "build_settings",
    "stream_seed",
    "epoch_offset_yr",
    "prior_sigmas",
    "min_transits",
    "star_sigmas",
]

#: Class key of the primary sources in the seeds and the results.
EXTRA_KEY = 0
TAG = 42  # Sect. 4.2: first element of every spawn key of this experiment
#: Stream numbers of the spawn keys (the population's is POPULATION_STREAM = 0).
DEAD_STREAM, ATTITUDE_STREAM, NOISE_STREAM, FACTOR_STREAM = 1, 2, 3, 4


def stream_seed(seed: int, stream: int, *key: int) -> np.random.SeedSequence:
    """The seed of one random stream of this experiment (module notes, "Reproducibility")."""
    return spawn(seed, TAG, stream, *key)


@dataclasses.dataclass(frozen=True, kw_only=True)
class PrimarySettings(GlobalSettings):
    """Everything the experiment needs besides its stars."""

    dead_time_fraction: float
    dead_time_outage_days: float
    priors: tuple
    knot_interval_days: float
    knot_transits: float | None
    knot_rule: str = "uniform"
    attitude_amplitude_mas: float
    attitude_timescale_days: float
    rtol: float
    update_tol_uas: float
    max_iter: int
    error_tol: float | None = None
    allow_unconverged: bool = False
    frame_fit: str = "precision"
    evaluation_epoch: str = "reference"
    basic_angle_harmonics: int = 0
    solver_start: str = "previous"

    @property
    def criterion(self) -> dict:
        """The PCG stopping rule as :func:`~mcsweep.solver.solve_global`'s keywords."""
        return dict(rtol=self.rtol, update_tol_uas=self.update_tol_uas, error_tol=self.error_tol,
                    max_iter=self.max_iter)

    def describe_criterion(self) -> str:
        """The stopping rule in words, for messages."""
        if self.error_tol is not None:
            return f"experiment.primary.solver_error_tol {self.error_tol:g}"
        return f"rtol {self.rtol:g} and {self.update_tol_uas:g} uas"

    def describe_state(self, last) -> str:
        """Where a solution stood after its last iteration (a history row), in the rule's terms."""
        e = float(last["error_estimate"])
        rule = (f"last update {last['update_max_uas']:.3g} uas" if self.error_tol is None else
                "error not yet estimated (too few iterations)" if math.isnan(e) else
                f"estimated error {e:.3g} of the formal uncertainties")
        return f"relative residual {last['relative_residual']:.2e}, {rule}"


def build_settings(config) -> PrimarySettings:
    """Settings from a checked :class:`~mcsweep.command.schema.Config`; user errors raised here."""
    pri = config.experiment.primary
    fields = global_fields(config, "primary")
    if pri.reference_epoch == "star_mean":
        raise UserInputError("experiment.primary.reference_epoch='star_mean' is not accepted; a global "
                             "solution has one reference epoch: expected 'dataset_mean' or an ISO date")
    priors = tuple(str(p) for p in pri.priors)
    for p in priors:
        parse_prior(p)
    if len(set(priors)) != len(priors) or not priors:
        raise UserInputError(f"experiment.primary.priors={list(priors)} is not accepted; expected a "
                             "non-empty list of distinct priors")
    if pri.basic_angle_harmonics and config.execution.backend == "dask":
        raise UserInputError(f"experiment.primary.basic_angle_harmonics={pri.basic_angle_harmonics} is not accepted "
                             "with execution=dask (the calibration's design is made on this machine); expected 0, "
                             "or execution.backend loky, threading or sequential")
    if max(list(pri.g_classes) + [pri.extra_g_min]) >= G_MAX:
        raise UserInputError(f"experiment.primary.g_classes={list(pri.g_classes)} / extra_g_min="
                             f"{pri.extra_g_min:g} is not accepted; expected magnitudes below {G_MAX:g}")
    return PrimarySettings(
        **fields,
        dead_time_fraction=float(pri.dead_time_fraction), dead_time_outage_days=float(pri.dead_time_outage_days),
        priors=priors, knot_interval_days=float(pri.knot_interval_hours) / 24.0,
        knot_transits=None if pri.knot_transits is None else float(pri.knot_transits), knot_rule=str(pri.knot_rule),
        attitude_amplitude_mas=float(pri.attitude_amplitude_mas),
        attitude_timescale_days=float(pri.attitude_timescale_hours) / 24.0,
        rtol=float(pri.solver_rtol), update_tol_uas=float(pri.solver_update_tol_uas),
        error_tol=None if pri.solver_error_tol is None else float(pri.solver_error_tol),
        max_iter=int(pri.solver_max_iter), allow_unconverged=bool(pri.allow_unconverged),
        frame_fit=str(pri.frame_fit), evaluation_epoch=str(pri.evaluation_epoch),
        basic_angle_harmonics=int(pri.basic_angle_harmonics), solver_start=str(pri.solver_start))


def epoch_offset_yr(settings: PrimarySettings, mean_tcb_jd) -> np.ndarray:
    """Each star's mean live epoch [TCB JD] relative to the reference epoch [yr]
    (``evaluation_epoch='star_mean'``)."""
    return (np.asarray(mean_tcb_jd) - settings.t_ref_jd) / JULIAN_YEAR_DAYS


def prior_sigmas(settings: PrimarySettings, label: str, l_deg, b_deg, g_mag) -> np.ndarray:
    """The parallax prior sigma [mas] of prior ``label`` for stars at (l, b, G) (Eqs. 14-17
    scaled, or a fixed sigma: :func:`~mcsweep.experiments.global_solution.priors.prior_sigma_mas`)."""
    return prior_sigma_mas(label, settings.sigma_f90_mas(l_deg, b_deg, g_mag))


def min_transits(settings: PrimarySettings) -> int:
    """Live FoV transits a star needs to be in the solution: 1 (AL only: a position needs two)."""
    return 2 if settings.noise.use_ac is False else 1


def star_sigmas(settings: PrimarySettings, stars, solved):
    """AL and AC (None: AL only) uncertainties per FoV transit of the solved stars [mas]
    (``stars``: a table or a mapping of its columns; ``solved``: indices, a mask or a slice)."""
    gs = np.asarray(stars["phot_g_mean_mag"])[solved]
    return settings.noise.sigma_al_mas(gs), (settings.noise.sigma_ac_mas(gs) if settings.noise.use_ac else None)
