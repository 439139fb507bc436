"""One-year global (primary) solution with the attitude from the same data (paper Sect. 4.2, Table 3).

The attitude is now *not* known: stars and attitude are solved together
(:mod:`mcsweep.solver`, AGIS-style PCG). Procedure, following Sect. 4.2:

1. *Stars.* The three classes of Table 2 (the ``class_size`` brightest stars fainter
   than G0 = 11, 15, 19 over the whole sky, drawn exactly as in the secondary
   experiment, :mod:`mcsweep.experiments.global_solution.classes`), and only
   those: the paper's global solution holds these 1.5e6 stars (Sect. 4: 5e5 per class)
   and determines the attitude from them, all with the prior. ``primary_sources`` (default
   0) adds that many extra stars (the brightest fainter than ``primary_g_min``) to the
   solution, an option *not* in the paper: well-observed extra stars add attitude
   information the paper's solution did not have (docs/table3.md). The default is reduced
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
   perturbations on hour-to-day scales was found; docs/table3.md): it is smooth on the
   knot scale as Gaia's attitude is on its tens-of-seconds knots, and the unmodelled part
   stays below the noise (measured: 100 mas instead of 10 leaves the attitude error
   unchanged to the 0.1 uas printed, docs/table3.md). A time scale close to the knot
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
interval), the attitude error the prior's bias causes does not (docs/table3.md).

Reproducibility: SeedSequence(seed, spawn_key=(42, stream, ...)): population of a class
(stream 0, class key round(100 G0); primaries key 0), dead time (1), true attitude (2),
measurement noise (3, key: the block of ``SOLVER_BLOCK_STARS`` solved stars, drawn in the block's
order). So results do not depend on n_jobs, chunking or where a block is built (the driver,
or a Dask worker: :mod:`~mcsweep.experiments.primary.cluster`); the transit search is
chunked over stars and re-assembled in star order. (Before the stars were kept on the
workers the noise was one stream over all blocks: the same statistics, other draws.)
"""

from __future__ import annotations

import dataclasses
import math
import numpy as np
import pandas as pd

from ...astrometry.confidence import inside as inside_ellipse
from ...astrometry.confidence import mahalanobis_sq
from ...astrometry.design import JULIAN_YEAR_DAYS
from ...astrometry.noise import G_MAX
from ...astrometry.solve import prior_diagonal
from ...errors import UserInputError
from ...scanning.ephemeris import gaia_position_au
from ...scanning.timeline import DeadTime
from ...solver.attitude_spline import DEGREE, sorted_epochs
from ...solver.reduction import pairwise_sum, run_level
from ...solver.blocks import att_rows, spline_values, src_forward
from ...solver import (SOLVER_BLOCK_STARS, AttitudeSpline, GlobalProblem, build_observations, frame_attitude,
                      in_block_order, make_blocks, precision_weights, solve_global, source_normals)
from ...solver.calibration import BasicAngleColumns, basic_angle_columns, calibration_design
from ...solver.executors import chunk_values
from ...solver.frame import frame_fit_sums, frame_from_sums, offsets_of
from ..global_solution.classes import dead_time, star_transits
from ..global_solution.priors import parse_prior, prior_sigma_mas
from ..global_solution.settings import GlobalSettings, global_fields, spawn
from .results import StarParts, solved_results

__all__ = [
    "PRIMARY_KEY",
    "TAG",
    "PrimarySettings",
    "PreparedData",
    "build_settings",
    "stream_seed",
    "transits_of",
    "positions_at",
    "prepare",
    "evaluate_solution",
    "solve_in_process",
    "attitude_error",
    "attitude_error_series",
]

#: Class key of the primary sources in the seeds and the results.
PRIMARY_KEY = 0
TAG = 42  # Sect. 4.2: first element of every spawn key of this experiment
#: Stream numbers of the spawn keys (the population's is POPULATION_STREAM = 0).
DEAD_STREAM, ATTITUDE_STREAM, NOISE_STREAM, FACTOR_STREAM = 1, 2, 3, 4


def stream_seed(seed: int, stream: int, *key: int) -> np.random.SeedSequence:
    return spawn(seed, TAG, stream, *key)


@dataclasses.dataclass(frozen=True, kw_only=True)
class PrimarySettings(GlobalSettings):
    """Everything the experiment needs besides its stars."""

    dead_time_fraction: float
    dead_time_block_days: float
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
    if max(list(pri.g_classes) + [pri.primary_g_min]) >= G_MAX:
        raise UserInputError(f"experiment.primary.g_classes={list(pri.g_classes)} / primary_g_min="
                             f"{pri.primary_g_min:g} is not accepted; expected magnitudes below {G_MAX:g}")
    return PrimarySettings(
        **fields,
        dead_time_fraction=float(pri.dead_time_fraction), dead_time_block_days=float(pri.dead_time_block_days),
        priors=priors, knot_interval_days=float(pri.knot_interval_hours) / 24.0,
        knot_transits=None if pri.knot_transits is None else float(pri.knot_transits), knot_rule=str(pri.knot_rule),
        attitude_amplitude_mas=float(pri.attitude_amplitude_mas),
        attitude_timescale_days=float(pri.attitude_timescale_hours) / 24.0,
        rtol=float(pri.solver_rtol), update_tol_uas=float(pri.solver_update_tol_uas),
        error_tol=None if pri.solver_error_tol is None else float(pri.solver_error_tol),
        max_iter=int(pri.solver_max_iter), allow_unconverged=bool(pri.allow_unconverged),
        frame_fit=str(pri.frame_fit), evaluation_epoch=str(pri.evaluation_epoch),
        basic_angle_harmonics=int(pri.basic_angle_harmonics), solver_start=str(pri.solver_start))


# --------------------------------------------------------------------------- data
def transits_of(job) -> tuple[int, dict]:
    """FoV transits of one chunk of stars (executor task): (chunk index, arrays)."""
    index, first, ra, dec, start_jd, end_jd, law = job
    # the field of view (1 byte per transit) for the basic-angle calibration (mcsweep.solver.calibration)
    return index, star_transits(ra, dec, start_jd, end_jd, law, first=first, with_fov=True)


@dataclasses.dataclass
class PreparedData:
    """Stars, observations and noisy measurements shared by every prior's solution.

    The measurements' partials live only in the solver's blocks (built block by block
    of stars, :func:`prepare`), not in a full :class:`~mcsweep.solver.Observations`:
    at the paper's 1.5e6 stars that would double the largest arrays of the run. Data built
    on a cluster (:func:`~mcsweep.experiments.primary.cluster.prepare_on_cluster`) keep the
    blocks, measurements, data normal matrices and truth on its workers: here ``blocks``
    are :class:`~mcsweep.solver.blocks.BlockSpan` s and ``h``, ``normals``, ``x_true`` None.
    """

    stars: pd.DataFrame      # STAR_COLUMNS + 'class_key' (round(100 G0), 0 = primary) + 'n_fov',
    #                          'epoch_offset_yr' (mean live epoch - reference), 'span_days' (live transits)
    solved: np.ndarray       # indices into ``stars`` of the stars in the solution (>= 1 transit)
    blocks: list             # solver StarBlocks of the solved stars (mcsweep.solver.make_blocks)
    normals: np.ndarray | None  # (n_solved, 5, 5) data normal matrices of the solved stars
    h: np.ndarray | None     # normalised measurements (observed minus computed from the law), problem order
    x_true: np.ndarray | None  # (n_solved, 5)
    spline: AttitudeSpline
    true_attitude: tuple     # (AttitudeSpline, coefficients (n, 3) [mas]): the true rotation
    t_ref_jd: float
    dead: DeadTime
    covered: np.ndarray      # (n_coef,) bool: spline coefficients with a measurement in their support
    n_rows: int | None = None  # measurements (None: h.size)
    naa_band: np.ndarray | None = None  # the attitude block's band when the blocks live on a cluster
    calibration: BasicAngleColumns | None = None  # the basic-angle variation's design, problem order
    # data built on a cluster: the table of stars there (primary_sky.SkyPartitions; ``stars`` and
    # ``solved`` are then None) and what the driver keeps of it (per partition its summaries'
    # futures and first solved star; the counts of solved stars and their transits)
    sky: object | None = None
    cluster: dict | None = None
    _problem: GlobalProblem | None = dataclasses.field(default=None, repr=False)
    _resident: tuple | None = dataclasses.field(default=None, repr=False)  # (key, DaskChunks)

    @property
    def dead_days(self) -> float:
        return self.dead.total_days

    @property
    def n_stars(self) -> int:
        """Stars of the solution's table (solved or not)."""
        return int(self.sky.n_stars) if self.sky is not None else len(self.stars)

    @property
    def n_solved(self) -> int:
        """Stars in the solution (with enough live transits)."""
        return int(self.cluster["n_solved"]) if self.cluster is not None else int(self.solved.size)

    @property
    def n_fov_transits(self) -> int:
        """Live FoV transits of the solved stars (the data of the attitude)."""
        if self.cluster is not None:
            return int(self.cluster["n_fov_transits"])
        return int(self.stars["n_fov"].to_numpy()[self.solved].sum())

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

    @property
    def n_measurements(self) -> int:
        return int(self.h.size) if self.n_rows is None else int(self.n_rows)

    def block_epochs(self, block) -> np.ndarray:
        """TCB JD of a block's measurements (:func:`_block_epochs`)."""
        return _block_epochs(self.t_ref_jd, block)

    def epochs(self) -> np.ndarray:
        """TCB JD of every measurement, in the problem's order."""
        return np.concatenate([self.block_epochs(b) for b in self.blocks]) if self.blocks else np.zeros(0)

    def true_attitude_at(self, tcb_jd) -> np.ndarray:
        """The true rotation (module notes, step 3) at ``tcb_jd`` [mas], (m, 3)."""
        return _rotation(self.true_attitude, tcb_jd)

    def problem(self, prior_diagonal) -> GlobalProblem:
        """The global problem under ``prior_diagonal``: assembled once from the blocks, then
        only the per-star inverses and frame weights change from prior to prior
        (:meth:`GlobalProblem.with_prior`, bit-identical to a new problem). Only the latest
        prior's inverses are kept (0.3 GB at 1.5e6 stars)."""
        if self._problem is None:
            st = self.stars
            self._problem = GlobalProblem.from_blocks(
                self.blocks, self.normals, prior_diagonal, st["ra"].to_numpy()[self.solved],
                st["dec"].to_numpy()[self.solved], n_coef=self.spline.n_coef, n_measurements=self.n_measurements,
                naa_band=self.naa_band)
        else:
            self._problem = self._problem.with_prior(prior_diagonal)
        return self._problem


    @property
    def on_cluster(self) -> bool:
        """Whether the blocks and measurements live on a cluster's workers (built there,
        :func:`~mcsweep.experiments.primary.cluster.prepare_on_cluster`)."""
        return self.h is None

    def keep_resident(self, client, ranges, chunks: "DaskChunks") -> None:
        """Hold ``chunks``, the solver's chunks of block ``ranges`` on the workers of ``client``."""
        self._resident = ((client, tuple(map(tuple, ranges))), chunks)

    def resident(self, client, ranges) -> "DaskChunks":
        """The solver's chunks (blocks ``ranges``, their measurements) kept on the workers of a
        Dask ``client``: sent once for every prior's solution (only the per-star inverses of
        a prior are sent with it, :meth:`~mcsweep.solver.dask_resident.DaskChunks.with_inverses`);
        built there already for data made on the cluster."""
        from ...solver.dask_resident import DaskChunks

        key = (client, tuple(map(tuple, ranges)))  # the client itself: a closed one's id may be reused
        if self._resident is not None and self._resident[0][0] is client and self._resident[0][1] == key[1]:
            return self._resident[1]
        if self.on_cluster:
            raise ValueError("these data were built on a cluster for other chunks or another client")
        self._resident = (key, DaskChunks.scatter(
            client, [(self.blocks[lo:hi], [self.h[b.rows] for b in self.blocks[lo:hi]]) for lo, hi in ranges]))
        return self._resident[1]

    def attitude_sq(self, coef, eps, omega, resident=None, ranges=None) -> np.ndarray:
        """Sum over the measurements of the squared attitude error (3,) [mas^2]: block by block
        (bounded temporaries), on the workers for data built there (``resident``, chunks of
        block ``ranges``), added in the fixed tree either way (the same bits)."""
        args = (coef, eps, omega, self.true_attitude, self.t_ref_jd)
        if self.on_cluster:
            out = chunk_values(resident.run, _attitude_sq_task, [(ci, *args) for ci in range(len(ranges))])
            total = pairwise_sum(out, None, [run_level(lo, hi) for lo, hi in ranges])
        else:
            total = pairwise_sum(_block_attitude_sq(b, *args) for b in self.blocks)
        return np.zeros(3) if total is None else total


def _block_attitude_sq(block, coef, eps, omega, true_attitude, t_ref_jd) -> np.ndarray:
    """One block's sum of squared attitude errors (3,), from its own spline values."""
    t = _block_epochs(t_ref_jd, block)
    err = spline_values(block, coef).T - _rotation(true_attitude, t) - frame_attitude(eps, omega, t, t_ref_jd)
    return np.sum(err ** 2, axis=0)


def _attitude_sq_task(item):
    ci, blocks, _, _, *args = item
    return ci, pairwise_sum(_block_attitude_sq(b, *args) for b in blocks)


def _block_epochs(t_ref_jd: float, block) -> np.ndarray:
    """TCB JD of a block's measurements, from the epochs the block stores (to ~1e-14 d)."""
    return t_ref_jd + JULIAN_YEAR_DAYS * block.t


def _rotation(true_attitude: tuple, tcb_jd) -> np.ndarray:
    """A (spline, coefficients) rotation at ``tcb_jd`` [mas], (m, 3)."""
    spline, coef = true_attitude
    return spline.evaluate(coef, tcb_jd)


def true_attitude(settings: PrimarySettings) -> tuple[AttitudeSpline, np.ndarray]:
    """The smooth random rotation (module notes, step 3): its spline and coefficients [mas]."""
    rng = np.random.default_rng(stream_seed(settings.seed, ATTITUDE_STREAM))
    timescale_days = settings.attitude_timescale_days
    shift_days = rng.uniform(0.0, timescale_days)  # knots off the solver's grid
    spline = AttitudeSpline(settings.start_jd - shift_days, settings.end_jd + timescale_days, timescale_days)
    return spline, rng.normal(0.0, settings.attitude_amplitude_mas, (spline.n_coef, 3))


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


def dead_time_of(settings: PrimarySettings) -> DeadTime:
    """The data set's dead time (one draw, its own stream)."""
    return dead_time(stream_seed(settings.seed, DEAD_STREAM), settings.start_jd, settings.end_jd,
                     settings.dead_time_fraction, block_days=settings.dead_time_block_days)


def transit_summary(star, t, dead: DeadTime, first: int, n: int) -> dict:
    """Per star ``first .. first + n - 1`` from its transits (``star``, TCB JD ``t``, sorted by
    star): ``n_fov`` (live FoV transits), ``n_scheduled`` (FoV transits before the dead time),
    ``mean_tcb_jd`` (mean live epoch, TCB JD), ``span_days`` (days between the first and last
    live transit); and
    ``live`` per transit. Each star's numbers are sums
    over its own transits in their order, so a chunk's equal the whole set's, bit for bit."""
    live = ~dead.is_dead(t)
    local = np.asarray(star, dtype=np.int64) - first
    n_fov = np.bincount(local, weights=live, minlength=n).astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_tcb_jd = np.bincount(local, weights=np.where(live, t, 0.0), minlength=n) / n_fov
    t_live = np.where(live, t, np.nan)
    span_days = np.full(n, np.nan)
    if local.size:
        starts = np.flatnonzero(np.r_[True, local[1:] != local[:-1]])
        with np.errstate(invalid="ignore"):
            span_days[local[starts]] = (np.fmax.reduceat(t_live, starts) - np.fmin.reduceat(t_live, starts))
    n_scheduled = np.bincount(local, minlength=n).astype(np.int64)
    return {"n_fov": n_fov, "n_scheduled": n_scheduled, "mean_tcb_jd": mean_tcb_jd, "span_days": span_days,
            "live": live}


def with_transit_columns(settings: PrimarySettings, stars: pd.DataFrame, summary: dict) -> pd.DataFrame:
    """``stars`` with ``n_fov``, ``n_fov_scheduled`` (before the dead time), ``epoch_offset_yr`` (each star's mean live epoch relative to the
    reference epoch: evaluation_epoch='star_mean') and ``span_days`` (the time spans of the
    <= 4 transit subset)."""
    stars = stars.copy()
    stars["n_fov"] = summary["n_fov"]
    stars["n_fov_scheduled"] = summary["n_scheduled"]
    stars["epoch_offset_yr"] = epoch_offset_yr(settings, summary["mean_tcb_jd"])
    stars["span_days"] = summary["span_days"]
    return stars


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


def solved_stars(settings: PrimarySettings, n_fov: np.ndarray) -> np.ndarray:
    """Indices of the stars in the solution (:func:`min_transits`)."""
    return np.flatnonzero(n_fov >= min_transits(settings))


def star_sigmas(settings: PrimarySettings, stars, solved):
    """AL and AC (None: AL only) uncertainties per FoV transit of the solved stars [mas]
    (``stars``: a table or a mapping of its columns; ``solved``: indices, a mask or a slice)."""
    gs = np.asarray(stars["phot_g_mean_mag"])[solved]
    return settings.noise.sigma_al_mas(gs), (settings.noise.sigma_ac_mas(gs) if settings.noise.use_ac else None)


def attitude_spline(settings: PrimarySettings, dead: DeadTime, epochs=None) -> AttitudeSpline:
    """The solver's spline: segments between the gaps, as AGIS; with ``knot_transits`` its knots
    placed by ``epochs``, the solution's live FoV transits (not needed otherwise): an array,
    or an object answering :class:`~mcsweep.solver.attitude_spline.SortedEpochs`' questions
    (the epochs on a cluster's workers, :mod:`~.primary_cluster`)."""
    gaps = (dead.starts, dead.stops)
    if settings.knot_transits is None:
        return AttitudeSpline(settings.start_jd, settings.end_jd, settings.knot_interval_days, gaps=gaps)
    epochs = sorted_epochs(epochs)
    return AttitudeSpline(settings.start_jd, settings.end_jd, solver_knot_interval_days(settings, epochs.size, dead),
                          gaps=gaps, epochs=epochs, transits_per_knot=settings.knot_transits, knot_rule=settings.knot_rule)


def prepare(settings: PrimarySettings, stars: pd.DataFrame, transits: dict, *,
            with_noise: bool = True, block_stars: int = SOLVER_BLOCK_STARS) -> PreparedData:
    """Dead time, observations of the stars with >= 1 transit, truth and noisy measurements.

    ``transits`` sorted by star (as :func:`transits_of` gives them). The solver's blocks
    are built block by block of ``block_stars`` stars (a property of the problem, as in
    :class:`~mcsweep.solver.GlobalProblem`): each block's partials exist twice only while
    it is built. The noise is drawn block by block in the order the measurements are
    built, the blocks' own (by time within each block).
    ``with_noise=False`` leaves the measurement noise out (tests).
    """
    star, t, psi = transits["star"], transits["t"], transits["psi"]
    harmonics = settings.basic_angle_harmonics
    following = transits.get("following") if harmonics else None
    if harmonics and following is None:
        raise ValueError("the basic-angle calibration needs each transit's field of view: transits from "
                         "transits_of (star_transits with with_fov=True)")
    if star.size and np.any(np.diff(star) < 0):
        raise ValueError("transits must be sorted by star")
    dead = dead_time_of(settings)
    summary = transit_summary(star, t, dead, 0, len(stars))
    live = summary.pop("live")
    stars = with_transit_columns(settings, stars, summary)
    solved = solved_stars(settings, summary["n_fov"])
    s_al_star, s_ac_star = star_sigmas(settings, stars, solved)
    in_solution = np.zeros(len(stars), dtype=bool)
    in_solution[solved] = True
    # knots placed by the solution's FoV transits (knot_transits)
    spline = attitude_spline(settings, dead, t[live & in_solution[star]] if settings.knot_transits is not None else None)
    n_fov = summary["n_fov"]
    t_ref = settings.t_ref_jd
    ra, dec = stars["ra"].to_numpy()[solved], stars["dec"].to_numpy()[solved]
    x_true = true_parameters(stars, solved)
    true_att = true_attitude(settings)
    counts = measurements_per_star(n_fov[solved], s_ac_star)
    h_all = np.empty(int(counts.sum()))
    cal_omega, cal_weight = (np.zeros(h_all.size), np.zeros(h_all.size)) if harmonics else (None, None)
    blocks, normals = [], []
    rows = block_rows(counts, block_stars)
    for k, first in enumerate(range(0, solved.size, block_stars)):
        last = min(first + block_stars, solved.size)
        blk, nrm, h, cal = build_block(
            BlockJob(first=first, ra=ra[first:last], dec=dec[first:last], x_true=x_true[first:last],
                     sigma_al_mas=s_al_star[first:last],
                     sigma_ac_mas=None if s_ac_star is None else s_ac_star[first:last],
                     noise_seed=stream_seed(settings.seed, NOISE_STREAM, k) if with_noise else None,
                     first_row=int(rows[k])),
            *block_transits(star, t, psi, live, solved[first:last], following), spline=spline,
            true_attitude=true_att, t_ref_jd=t_ref, block_stars=block_stars, law=settings.law, harmonics=harmonics)
        h_all[blk.rows] = h
        if cal is not None:
            cal_omega[blk.rows], cal_weight[blk.rows] = cal.omega, cal.weight
        blocks.append(blk)
        normals.append(nrm)
    return PreparedData(stars=stars, solved=solved, blocks=blocks,
                        normals=np.concatenate(normals) if normals else np.zeros((0, 5, 5)), h=h_all,
                        x_true=x_true, spline=spline, true_attitude=true_att, t_ref_jd=t_ref,
                        dead=dead, covered=covered_coefficients(blocks, spline.n_coef),
                        calibration=None if not harmonics else
                        BasicAngleColumns(omega=cal_omega, weight=cal_weight, harmonics=harmonics))


def true_parameters(stars, solved) -> np.ndarray:
    """The truth of the solved stars (n, 5): position zero at the reference epoch (the offsets
    are what is solved for), the population's parallax and proper motion. ``stars``: a table
    or a mapping of its columns; ``solved``: indices or a slice."""
    plx = np.asarray(stars["parallax"])[solved]
    zero = np.zeros(plx.size)
    return np.column_stack([zero, zero, plx, np.asarray(stars["pmra"])[solved], np.asarray(stars["pmdec"])[solved]])


def measurements_per_star(n_fov: np.ndarray, sigma_ac_mas) -> np.ndarray:
    """One AL measurement per live FoV transit, one AC where its sigma is finite."""
    return np.asarray(n_fov, dtype=np.int64) * (1 + (np.isfinite(sigma_ac_mas) if sigma_ac_mas is not None else 0))


def block_rows(counts: np.ndarray, block_stars: int) -> np.ndarray:
    """First measurement (observation order = block order) of each block of ``block_stars`` stars."""
    if not counts.size:
        return np.zeros(0, np.int64)
    return first_rows(np.add.reduceat(counts, np.arange(0, counts.size, block_stars)))


def first_rows(per_block: np.ndarray) -> np.ndarray:
    """First measurement of each block from the blocks' numbers of measurements."""
    return np.concatenate([[0], np.cumsum(per_block)[:-1]]).astype(np.int64) if len(per_block) else \
        np.zeros(0, np.int64)


def block_transits(star, t, psi, live, solved_block: np.ndarray, following=None):
    """The live transits of one block's stars ``solved_block`` (sorted star indices) among
    transits sorted by star that include all of theirs: (star within the block, t, psi,
    ``following`` of those transits or None)."""
    lo, hi = np.searchsorted(star, [solved_block[0], solved_block[-1] + 1])
    idx = np.searchsorted(solved_block, star[lo:hi])
    # (AL only: a star of one transit lies in the range without being solved)
    ok = live[lo:hi] & (solved_block[np.minimum(idx, solved_block.size - 1)] == star[lo:hi])
    return idx[ok], t[lo:hi][ok], psi[lo:hi][ok], None if following is None else following[lo:hi][ok]


def covered_coefficients(blocks, n_coef: int) -> np.ndarray:
    """Which spline coefficients (per axis) have a measurement in their support."""
    covered = np.zeros(n_coef, dtype=bool)
    for b in blocks:  # the runs of equal first coefficient: a few per knot and block
        covered[(b.seg_j0[:, None] + np.arange(DEGREE + 1)).ravel()] = True
    return covered


@dataclasses.dataclass(frozen=True, kw_only=True)
class BlockJob:
    """What one block of solved stars needs besides its transits and the shared spline and truth:
    its first star (in the solution), the stars' directions [deg], true parameters (n, 5),
    uncertainties [mas] (AC None: AL only), the seed of its noise (None: none) and its first
    measurement in the problem's observation order."""

    first: int
    ra: np.ndarray
    dec: np.ndarray
    x_true: np.ndarray
    sigma_al_mas: np.ndarray
    sigma_ac_mas: np.ndarray | None
    noise_seed: np.random.SeedSequence | None
    first_row: int


def build_block(job: BlockJob, star, t, psi, following=None, *, spline: AttitudeSpline, true_attitude: tuple,
                t_ref_jd: float, block_stars: int, law=None, harmonics: int = 0):
    """One solver block from its stars' live transits (``star`` within the block, TCB JD ``t``,
    scan angle ``psi`` [deg]): (StarBlock, data normal matrices (n, 5, 5), normalised
    measurements, calibration design). The last is None, or with ``harmonics > 0`` the
    block's part of a basic-angle variation of the scanning ``law``
    (:func:`~mcsweep.solver.calibration.basic_angle_columns`, from each transit's field of
    view ``following``), in the block's order.

    The same function wherever the block is built (in the driver, :func:`prepare`, or on a Dask
    worker, :mod:`~mcsweep.experiments.primary.cluster`), so the data are the same bits. The
    measurements are truth plus the true attitude (module notes, step 3) through the very
    partials the solver holds, plus unit noise from the block's own seed (the block's
    identity, so neither the chunking nor where it is built changes it) in the block's order
    (by time).
    """
    obs = build_observations(job.ra, job.dec, star, t, psi, gaia_position_au(t), t_ref_jd=t_ref_jd,
                             sigma_al_mas=job.sigma_al_mas[star],
                             sigma_ac_mas=None if job.sigma_ac_mas is None else job.sigma_ac_mas[star],
                             spline=spline)
    # Observation order = block order: each block's measurements are then a contiguous
    # slice of h, read as a view by the solver (no index array, no per-solution copy).
    (blk,) = make_blocks(obs, job.ra, job.dec, block_stars=block_stars, first_star=job.first)
    cal = None
    if harmonics:
        # obs holds the AL measurements in transit order, then the AC ones (build_observations),
        # which get weight zero (any transit index in range serves them)
        order = blk.rows
        transit = np.where(order < t.size, order, order - t.size)
        cal = basic_angle_columns(obs.tcb_jd[order], np.asarray(following)[transit],
                                  job.sigma_al_mas[star[transit]], obs.is_ac[order], law, harmonics)
    (blk,) = in_block_order([blk], job.first_row)
    normals = source_normals(obs)
    del obs
    rot = _rotation(true_attitude, _block_epochs(t_ref_jd, blk))  # (m, 3) [mas]
    h = src_forward(blk, job.x_true)
    for c, rows in enumerate(att_rows(blk)):
        h += rows * rot[:, c]
    if job.noise_seed is not None:
        h += np.random.default_rng(job.noise_seed).standard_normal(h.size)
    return blk, normals, h, cal


def attitude_error(data: PreparedData, coef, eps, omega, tcb_jd, estimated=None) -> np.ndarray:
    """Estimated minus true attitude after the frame correction at ``tcb_jd`` [mas], (m, 3);
    ``estimated``: the solution's attitude at ``tcb_jd`` if already known (m, 3)."""
    est = data.spline.evaluate(coef, tcb_jd) if estimated is None else estimated
    return est - data.true_attitude_at(tcb_jd) - frame_attitude(eps, omega, tcb_jd, data.t_ref_jd)


def attitude_error_series(data: PreparedData, coef, eps, omega, *, per_knot: int = 1) -> pd.DataFrame:
    """The attitude error on a regular grid (``per_knot`` points per knot interval, at
    interval centres), live time only (the spline has no segment in the dead time): columns ``tcb_jd``, ``x_uas``, ``y_uas``, ``z_uas``."""
    step = data.spline.knot_interval_days / per_knot
    t = data.spline.start_jd + step * (0.5 + np.arange(int(round((data.spline.end_jd - data.spline.start_jd)
                                                                   / step))))
    t = t[data.spline.segment_of(t) >= 0]  # live time: the spline's segments
    err = 1e3 * attitude_error(data, coef, eps, omega, t)
    return pd.DataFrame({"tcb_jd": t, "x_uas": err[:, 0].astype(np.float32), "y_uas": err[:, 1].astype(np.float32),
                         "z_uas": err[:, 2].astype(np.float32)})


def positions_at(x, cov, tau_yr) -> tuple[np.ndarray, np.ndarray]:
    """Position offsets (n, 2) [mas] and their covariances (n, 2, 2) at ``tau_yr`` Julian years
    from the reference epoch, from five-parameter offsets ``x (n, 5)`` and covariances
    ``cov (n, 5, 5)`` there: ``position + tau_yr * proper motion`` (Eq. 1's linear motion),
    exactly. The prior of Eq. 18 constrains only parallax and proper motion, so this equals a
    solution referred to the epoch ``tau_yr`` itself (tests)."""
    tau_yr = np.asarray(tau_yr, dtype=float)
    C = np.asarray(cov, dtype=float)
    pos = x[:, :2] + tau_yr[:, None] * x[:, 3:5]
    cov_pos = (C[:, :2, :2] + tau_yr[:, None, None] * (C[:, :2, 3:5] + C[:, 3:5, :2])
               + (tau_yr ** 2)[:, None, None] * C[:, 3:5, 3:5])
    return pos, cov_pos


def block_frame_sums(K, binv, dx, equal: bool) -> np.ndarray:
    """One block's part of the frame rotator's fit (Lindegren et al. 2012, Sect. 6.1): weighted
    by the formal precisions (``equal``: every star alike); unweighted, the arcsec errors of
    1-2-transit stars under 1000 mas set it. The same function wherever the block is."""
    return frame_fit_sums(K, np.ones((len(dx), 2)) if equal else precision_weights(binv), dx)


def block_outcome(K, binv, dx, eps, omega, tau_yr, confidence: float):
    """Per star of one block, after removing the fitted rotation ``eps`` and spin ``omega``:
    inside the P ellipse (1/0; -1 without a confidence region: the project's one inside rule),
    the position error [mas] (at ``tau_yr`` Julian years from the reference epoch if given) and
    the parallax error [mas]."""
    dx = dx - offsets_of(K, eps, omega)
    pos, cov_pos = dx[:, :2], binv[:, :2, :2]
    if tau_yr is not None:
        pos, cov_pos = positions_at(dx, binv, tau_yr)
    good = np.isfinite(mahalanobis_sq(pos, cov_pos))
    inside = np.full(len(dx), -1, dtype=np.int8)
    inside[good] = inside_ellipse(pos[good], cov_pos[good], confidence)
    return inside, np.hypot(pos[:, 0], pos[:, 1]), dx[:, 2].copy()


def evaluate_solution(K, cov, dx, views, *, equal: bool, tau_yr, confidence: float):
    """``(eps, omega, (inside, err_mas, err_parallax_mas))`` of a solution held in this process:
    the frame rotator fitted to its errors ``dx (n, 5)`` block by block (``views``: the blocks'
    slices, summed in the fixed tree as on a cluster; ``equal``: every star alike) and each
    star's outcome after removing it (:func:`block_outcome`; ``tau_yr``: epochs of evaluation,
    Julian years from the reference epoch, None for the reference epoch)."""
    eps, omega = frame_from_sums(pairwise_sum(block_frame_sums(K[v], cov[v], dx[v], equal) for v in views)
                                 if views else np.zeros(24))
    parts = [block_outcome(K[v], cov[v], dx[v], eps, omega, None if tau_yr is None else tau_yr[v], confidence)
             for v in views]
    return eps, omega, tuple(np.concatenate([p[i] for p in parts]) if parts else np.zeros(0) for i in range(3))


def solve_in_process(settings: PrimarySettings, data: PreparedData, label: str, log=None, *, chunk_stars=None,
                     workers: int = 1, dask_client=None, attitude_start=None, equal: bool = False) -> tuple:
    """One global solution of data held in this process (the driver holds every star's
    arrays; ``dask_client``: the measurements' chunks are kept on its workers from prior to
    prior): ``(solution, resident chunks or None, eps, omega, StarParts, attitude error
    sums)``, the same as :func:`~.primary_cluster.solve_on_cluster` gives for data on a
    cluster. Arguments as :func:`~.primary_solution.solve_prior`."""
    st = data.stars
    s = data.solved
    sig = prior_sigmas(settings, label, st["l"].to_numpy()[s], st["b"].to_numpy()[s],
                       st["phot_g_mean_mag"].to_numpy()[s])
    tau_yr = st["epoch_offset_yr"].to_numpy()[s] if settings.evaluation_epoch == "star_mean" else None
    prior = prior_diagonal(sig, settings.ratio_R)
    # Raises if a star's block is singular: every solved star has >= 1 AL+AC or 2 AL
    # measurements, so it cannot be under a positive prior.
    problem = data.problem(prior)
    resident = None
    if dask_client is not None:  # the measurements stay on the workers from prior to prior
        ranges = problem.chunks(chunk_stars)
        stars = [slice(data.blocks[lo].first, data.blocks[hi - 1].first + data.blocks[hi - 1].n)
                 for lo, hi in ranges]
        resident = data.resident(dask_client, ranges).with_inverses([problem.src_inv[sl] for sl in stars])
    # with the basic-angle calibration (mcsweep.solver.calibration) its unknowns border the
    # system (mcsweep.solver.calibration)
    sol = solve_global(problem, data.h, **settings.criterion, log=log, chunk_stars=chunk_stars,
                       residuals=False, workers=workers, resident_chunks=resident,
                       border=None if data.calibration is None else calibration_design(data.calibration),
                       attitude_start=attitude_start)
    eps, omega, (inside_s, err_s, plx_s) = evaluate_solution(
        problem.K, sol.cov, sol.x - data.x_true, [slice(b.first, b.first + b.n) for b in data.blocks],
        equal=equal, tau_yr=tau_yr, confidence=settings.confidence)
    sq = data.attitude_sq(sol.attitude, eps, omega)
    results = StarParts.of_frame(solved_results(0, st["class_key"].to_numpy(), st["n_fov"].to_numpy(),
                                                st["n_fov_scheduled"].to_numpy(), st["span_days"].to_numpy(),
                                                s, (inside_s, err_s, plx_s, sig)))
    return sol, resident, eps, omega, results, sq
