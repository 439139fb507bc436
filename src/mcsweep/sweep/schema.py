"""Typed schemas of the configuration (Hydra structured configs).

The dataclasses are registered in Hydra's ConfigStore as ``base_config`` and named
first in ``conf/config.yaml``'s defaults list, so a value of the wrong type or an
unknown key fails at compose time. Ranges are checked in ``__post_init__``, which
runs when the composed config is turned into objects with
:func:`omegaconf.OmegaConf.to_object` (see :func:`mcsweep.sweep.validate.to_config`);
each check raises :class:`mcsweep.errors.UserInputError` with one line naming the key,
the value and what is accepted.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

from hydra.core.config_store import ConfigStore

from ..astrometry.noise import G_MAX
from ..errors import UserInputError
from ..prior.maps import MAX_NSIDE
from ..scanning.law import ScanningLaw

__all__ = [
    "SkyConf",
    "MagnitudesConf",
    "PriorGridConf",
    "ObservationsConf",
    "NoiseConf",
    "PopulationConf",
    "ScanningConf",
    "CellConf",
    "ShowcaseConf",
    "SecondaryConf",
    "RealSkyConf",
    "ExperimentConf",
    "ExecutionConf",
    "ResumeConf",
    "Config",
    "IGNORED_BY_EXPERIMENT",
    "register_configs",
]


def _require(ok: bool, key: str, value: Any, accepted: str) -> None:
    if not ok:
        raise UserInputError(f"{key}={value!r} is not accepted; expected {accepted}")


def _tcb_jd(key: str, iso: str) -> float:
    """TCB Julian date of an ISO date inside the observer-ephemeris table, else a one-line error."""
    from ..scanning.ephemeris import TABLE_END_JD_TCB, TABLE_START_JD_TCB
    from ..scanning.timescale import tcb_jd

    jd = tcb_jd(str(iso), key)
    _require(TABLE_START_JD_TCB <= jd <= TABLE_END_JD_TCB, key, iso, "a date within 2013-2031 (TCB)")
    return jd


def _check_reference_epoch(key: str, value: str) -> None:
    """A reference-epoch setting: 'dataset_mean', 'star_mean' or an ISO date within 2013-2031 (TCB)."""
    if value in ("dataset_mean", "star_mean"):
        return
    try:
        _tcb_jd(key, value)
    except UserInputError:
        raise UserInputError(f"{key}={value!r} is not accepted; expected 'dataset_mean', 'star_mean' or an "
                             "ISO date within 2013-2031 (TCB) such as '2017-01-23T00:00:00'") from None


@dataclass
class SkyConf:
    """Directions of the pencil beams (Sect. 3.4: 48 directions uniform on the sky)."""

    name: str = "healpix48"
    #: 'healpix' (pixel centres) or 'list' (explicit directions).
    kind: str = "healpix"
    nside: int = 2
    #: HEALPix pixel ordering: 'nested' or 'ring'.
    order: str = "nested"
    #: Frame of the HEALPix grid or of the listed directions: 'galactic' or 'icrs'.
    frame: str = "galactic"
    #: Explicit directions as [lon, lat] pairs in degrees (frame above), kind='list'.
    directions: List[Any] = field(default_factory=list)

    def __post_init__(self):
        _require(self.kind in ("healpix", "list"), "sky.kind", self.kind, "'healpix' or 'list'")
        _require(self.frame in ("galactic", "icrs"), "sky.frame", self.frame, "'galactic' or 'icrs'")
        if self.kind == "healpix":
            _require(self.nside >= 1 and (self.nside & (self.nside - 1)) == 0,
                     "sky.nside", self.nside, "a power of two >= 1")
            _require(self.order in ("nested", "ring"), "sky.order", self.order, "'nested' or 'ring'")
        else:
            _require(len(self.directions) > 0, "sky.directions", self.directions,
                     "a non-empty list of [lon_deg, lat_deg] pairs")
            for d in self.directions:
                ok = isinstance(d, (list, tuple)) and len(d) == 2 and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) for v in d)
                _require(ok and 0.0 <= d[0] <= 360.0 and -90.0 <= d[1] <= 90.0, "sky.directions",
                         list(d) if isinstance(d, (list, tuple)) else d,
                         "[lon_deg in 0..360, lat_deg in -90..90] pairs")
            self.directions = [[float(v) for v in d] for d in self.directions]


@dataclass
class MagnitudesConf:
    """G-magnitude bin edges (paper Fig. 4: G = 6-20 in 1 mag bins)."""

    name: str = "g6_20"
    edges: List[float] = field(default_factory=lambda: [float(g) for g in range(6, 21)])

    def __post_init__(self):
        e = list(self.edges)
        _require(len(e) >= 2, "magnitudes.edges", e, "at least two bin edges")
        _require(all(0.0 <= g <= G_MAX for g in e), "magnitudes.edges", e,
                 f"G values within 0..{G_MAX:g} mag (the noise model's range)")
        _require(all(b > a for a, b in zip(e[:-1], e[1:])), "magnitudes.edges", e,
                 "strictly increasing edges (non-empty bins)")


@dataclass
class PriorGridConf:
    """Logarithmic grid of parallax prior sigmas sigma_plx_p [mas] (Sect. 3.2-3.3)."""

    name: str = "default"
    min_mas: float = 0.01
    max_mas: float = 1000.0
    n: int = 41

    def __post_init__(self):
        _require(self.min_mas > 0, "prior_grid.min_mas", self.min_mas, "a positive prior sigma in mas")
        _require(self.max_mas > self.min_mas, "prior_grid.max_mas", self.max_mas,
                 f"a value larger than prior_grid.min_mas={self.min_mas}")
        _require(self.n >= 2, "prior_grid.n", self.n, "at least 2 grid values")


@dataclass
class ObservationsConf:
    """Which FoV transits a pencil-beam cell uses (paper Table 1 and Fig. 3)."""

    name: str = "paper"
    #: Interval of scanning-law transits, ISO dates in TCB (Sect. 3.1: Oct 2014 - end 2015).
    start: str = "2014-10-01T00:00:00"
    end: str = "2016-01-01T00:00:00"
    #: Observation cases: name -> list of 0-based distinct-transit groups; negative
    #: indices count from the last group ("two_diluted" = first and last, Fig. 3).
    cases: Dict[str, List[int]] = field(default_factory=lambda: {
        "one": [0], "two": [0, 1], "two_diluted": [0, -1],
        "four": [0, 1, 2, 3], "eight": [0, 1, 2, 3, 4, 5, 6, 7]})
    #: The case that fixes sigma_F90 (Sect. 3.3: two distinct consecutive transits).
    f90_case: str = "two"
    #: 'mean' = each star's mean epoch of the observations used (Sect. 2.1), or 'fixed'.
    reference_epoch: str = "mean"
    #: Reference epoch (ISO, TCB) when reference_epoch='fixed'.
    fixed_epoch: str = "2015-06-01T00:00:00"

    def __post_init__(self):
        _require(len(self.cases) > 0, "observations.cases", dict(self.cases), "at least one case")
        for k, v in self.cases.items():
            _require(len(v) > 0, f"observations.cases.{k}", list(v), "a non-empty list of group indices")
        _require(self.f90_case in self.cases, "observations.f90_case", self.f90_case,
                 f"one of the cases {sorted(self.cases)}")
        _require(self.reference_epoch in ("mean", "fixed"), "observations.reference_epoch",
                 self.reference_epoch, "'mean' or 'fixed'")
        start, end = (_tcb_jd(f"observations.{k}", getattr(self, k)) for k in ("start", "end"))
        _tcb_jd("observations.fixed_epoch", self.fixed_epoch)
        _require(end > start, "observations.end", self.end, f"a date after observations.start={self.start}")


@dataclass
class NoiseConf:
    """Per-FoV-transit measurement precision (see mcsweep.astrometry.noise)."""

    name: str = "gaia"
    #: Multiplies the along-scan precision of the published model.
    al_scale: float = 1.0
    #: Multiplies the across-scan precision of the published model.
    ac_scale: float = 1.0
    #: Whether AC measurements enter the solution (they matter for G < 10).
    use_ac: bool = True
    #: Extra AL error per FoV transit [mas], added in quadrature (calibration-limited
    #: floor of bright stars; 0 = the published model alone; preset noise=edr3_floor).
    al_floor_mas: float = 0.0

    def __post_init__(self):
        _require(self.al_scale > 0, "noise.al_scale", self.al_scale, "a positive factor")
        _require(self.ac_scale > 0, "noise.ac_scale", self.ac_scale, "a positive factor")
        _require(math.isfinite(self.al_floor_mas) and self.al_floor_mas >= 0, "noise.al_floor_mas",
                 self.al_floor_mas, "a non-negative finite AL error per FoV transit in mas")


@dataclass
class PopulationConf:
    """Source of 'true' stars: the built-in galaxy model or a catalogue file."""

    name: str = "galaxy_model"
    #: Catalogue file (FITS, VOTable, CSV or Parquet) when name='catalogue'.
    path: Optional[str] = None
    #: Catalogue format override ('auto', 'fits', 'votable', 'csv', 'parquet').
    format: str = "auto"
    #: Catalogue column mapping, ours -> theirs (e.g. {parallax: plx}).
    columns: Dict[str, str] = field(default_factory=dict)
    #: Catalogue units that differ from ours, ours -> unit (e.g. {parallax: arcsec}).
    units: Dict[str, str] = field(default_factory=dict)
    #: Catalogue rows with NaN in a needed column: 'error' or 'drop'.
    on_missing: str = "error"
    #: Galaxy-model parameters passed to GalaxyModel(**params).
    params: Dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        _require(self.name in ("galaxy_model", "catalogue"), "population", self.name,
                 "'galaxy_model' or 'catalogue'")
        _require(self.on_missing in ("error", "drop"), "population.on_missing", self.on_missing,
                 "'error' or 'drop'")
        if self.name == "catalogue":
            _require(bool(self.path), "population.path", self.path, "the path of a catalogue file")


_LAW = ScanningLaw()


@dataclass
class ScanningConf:
    """Scanning law; the fields of mcsweep.scanning.ScanningLaw (Sect. 3.1; conf/scanning/).

    Defaults and range checks are ScanningLaw's own (the flown law: a list of segments,
    mcsweep.scanning.segments; the top-level phases are for a one-segment law, ``nominal``).
    """

    name: str = _LAW.name
    spin_rate_arcsec_s: float = _LAW.spin_rate_arcsec_s
    solar_aspect_deg: float = _LAW.solar_aspect_deg
    precession_S: float = _LAW.precession_S
    ref_epoch_tcb: Optional[str] = _LAW.ref_epoch_tcb
    nu_ref_deg: Optional[float] = _LAW.nu_ref_deg
    omega_ref_deg: Optional[float] = _LAW.omega_ref_deg
    basic_angle_deg: float = _LAW.basic_angle_deg
    ac_limits_p_deg: List[float] = field(default_factory=lambda: list(_LAW.ac_limits_p_deg))
    ac_limits_f_deg: List[float] = field(default_factory=lambda: list(_LAW.ac_limits_f_deg))
    #: Segments (kind, start_tcb, end_tcb, ref_epoch_tcb, nu_ref_deg, omega_ref_deg); [] with the phases above.
    segments: List[Any] = field(default_factory=lambda: [s.as_dict() for s in _LAW.segments])

    def __post_init__(self):
        ScanningLaw.from_config(dataclasses.asdict(self))  # raises UserInputError


@dataclass
class CellConf:
    """Pencil-beam cell procedure (Sect. 3.2-3.4); each value changes the answer."""

    #: Radius of the pencil beam (Table 1: 1 deg).
    beam_radius_deg: float = 1.0
    #: Cap on the stars drawn per cell (an unbiased subsample of the cone).
    max_stars: int = 20000
    #: Bright cells hold few stars: widen the beam around the same centre until this
    #: many stars are expected (all observed with the centre's transits).
    min_stars: int = 20000
    #: Largest radius the widening may reach.
    max_radius_deg: float = 20.0
    #: Interpolation of sigma_F90 between grid points: 'log' (in log sigma) or 'none'.
    interpolation: str = "log"
    #: Bootstrap resamples of the cell's stars for the sigma_F90 interval (0 = none).
    n_bootstrap: int = 200
    #: p_error_mas and median_semi_major_mas on every grid row of every cell (true), or
    #: only at sigma_F90 and in the showcase cell (false: NaN on the other grid rows).
    grid_statistics: bool = False

    def __post_init__(self):
        _require(self.n_bootstrap >= 0, "cell.n_bootstrap", self.n_bootstrap,
                 "a number of resamples >= 0")
        _require(0 < self.beam_radius_deg <= 90, "cell.beam_radius_deg", self.beam_radius_deg,
                 "a radius in (0, 90] deg")
        _require(self.max_stars > 0, "cell.max_stars", self.max_stars, "a positive number of stars")
        _require(self.min_stars > 0, "cell.min_stars", self.min_stars, "a positive number of stars")
        _require(self.max_radius_deg >= self.beam_radius_deg, "cell.max_radius_deg",
                 self.max_radius_deg, f">= cell.beam_radius_deg={self.beam_radius_deg}")
        _require(self.interpolation in ("log", "none"), "cell.interpolation", self.interpolation,
                 "'log' or 'none'")


@dataclass
class ShowcaseConf:
    """The single-direction experiment of the paper's Figs. 1-3 (Table 1 beam)."""

    enabled: bool = True
    ra_deg: float = 157.5
    dec_deg: float = 0.0
    g_min: float = 14.5
    g_max: float = 15.5
    #: Very tight and very loose priors of Fig. 2 (A and C), mas.
    tight_prior_mas: float = 0.01
    loose_prior_mas: float = 1000.0

    def __post_init__(self):
        _require(0 <= self.ra_deg < 360, "experiment.showcase.ra_deg", self.ra_deg, "0..360 deg")
        _require(-90 <= self.dec_deg <= 90, "experiment.showcase.dec_deg", self.dec_deg, "-90..90 deg")
        _require(0 <= self.g_min < self.g_max <= G_MAX, "experiment.showcase.g_min/g_max",
                 (self.g_min, self.g_max), f"0 <= g_min < g_max <= {G_MAX:g}")
        _require(self.tight_prior_mas > 0 and self.loose_prior_mas > self.tight_prior_mas,
                 "experiment.showcase priors", (self.tight_prior_mas, self.loose_prior_mas),
                 "0 < tight_prior_mas < loose_prior_mas")


@dataclass
class SecondaryConf:
    """Whole-sky secondary solution of Sect. 4.1 (Table 2)."""

    #: Stars per magnitude class: the brightest ones fainter than each of g_classes.
    class_size: int = 500_000
    g_classes: List[float] = field(default_factory=lambda: [11.0, 15.0, 19.0])
    #: Probability that a FoV transit is removed (Sect. 4.1: 95 %).
    dilution: float = 0.95
    mission_years: float = 5.0
    mission_start: str = "2014-07-25T10:30:00"
    #: 'paper' (Eqs. 14-17) or the path of a run directory's coefficients.csv.
    f90_formula: str = "paper"
    #: Reference epoch of the astrometric parameters (Sect. 2.1): 'dataset_mean' (mid-point
    #: of the mission, one epoch for all stars), 'star_mean' (each star's mean epoch) or an
    #: ISO date (TCB).
    reference_epoch: str = "dataset_mean"

    def __post_init__(self):
        _check_reference_epoch("experiment.secondary.reference_epoch", self.reference_epoch)
        _require(self.class_size > 0, "experiment.secondary.class_size", self.class_size, "a positive number")
        _require(len(self.g_classes) > 0 and all(0 <= g < G_MAX for g in self.g_classes),
                 "experiment.secondary.g_classes", list(self.g_classes), f"G values within 0..{G_MAX:g}")
        _require(0 <= self.dilution < 1, "experiment.secondary.dilution", self.dilution, "a probability in [0, 1)")
        _require(0 < self.mission_years <= 10, "experiment.secondary.mission_years", self.mission_years,
                 "a length in (0, 10] years")


@dataclass
class RealSkyConf:
    """Real-sky validation with Hipparcos stars as truth; documented in
    conf/experiment/real_sky.yaml and :mod:`mcsweep.experiments.real_sky`."""

    #: G range of the Hipparcos stars (G derived from Hp and the colours).
    g_min: float = 6.0
    g_max: float = 9.0
    #: Observation cases of ``observations.cases`` solved (Fig. 3's visits).
    cases: List[str] = field(default_factory=lambda: ["one", "two", "four", "eight"])
    #: 0: every star of the G range; else an unbiased seeded subset of that many.
    max_stars: int = 0
    #: The prior besides the paper's: 'paper' (only the paper's) or a sweep run directory.
    f90_formula: str = "paper"
    #: Multiplier of sigma_F90 (k sigma_F90 with Eq. 18).
    factor: float = 1.0

    def __post_init__(self):
        _require(0 <= self.g_min < self.g_max <= 21, "experiment.real_sky.g_min/g_max", (self.g_min, self.g_max),
                 "0 <= g_min < g_max <= 21")
        _require(len(self.cases) > 0 and len(set(self.cases)) == len(self.cases), "experiment.real_sky.cases",
                 list(self.cases), "a non-empty list of distinct observation case names")
        _require(self.max_stars >= 0, "experiment.real_sky.max_stars", self.max_stars,
                 "0 (all stars) or a positive number of stars")
        _require(self.factor > 0 and math.isfinite(self.factor), "experiment.real_sky.factor", self.factor,
                 "a positive, finite multiplier")


#: Most harmonics of the spin phase in a basic-angle variation solved with the primary
#: solution: each adds two unknowns bordering its normal equations (mcsweep.solver.calibration),
#: each 8 bytes per measurement on the driver.
MAX_BASIC_ANGLE_HARMONICS = 8
#: ``experiment.primary.knot_rule``'s values: those of :data:`mcsweep.solver.attitude_spline.KNOT_RULES`
#: (not imported: the solver's compiled kernels would load with every config; a test keeps them equal).
KNOT_RULES = ("counts", "uniform")


@dataclass
class PrimaryConf:
    """One-year global solution with the attitude of Sect. 4.2 (Table 3); documented in
    conf/experiment/primary.yaml and :mod:`mcsweep.experiments.primary`."""

    class_size: int = 30000
    g_classes: List[float] = field(default_factory=lambda: [11.0, 15.0, 19.0])
    primary_sources: int = 0
    primary_g_min: float = 13.0
    mission_years: float = 1.0
    mission_start: str = "2014-07-25T10:30:00"
    dead_time_fraction: float = 0.2
    dead_time_block_days: float = 0.25
    priors: List[str] = field(default_factory=lambda: ["F90", "10F90", "1000mas"])
    f90_formula: str = "paper"
    reference_epoch: str = "dataset_mean"
    # [h] in the config; the code holds days (experiments.primary.PrimarySettings.knot_interval_days)
    knot_interval_hours: float = 3.0
    knot_transits: Optional[float] = None
    knot_rule: str = "uniform"
    attitude_amplitude_mas: float = 10.0
    # [h] in the config; the code holds days (PrimarySettings.attitude_timescale_days)
    attitude_timescale_hours: float = 24.0
    solver_error_tol: Optional[float] = 0.01
    solver_rtol: float = 1e-8
    solver_update_tol_uas: float = 1e-2
    solver_max_iter: int = 2000
    solver_start: str = "previous"
    allow_unconverged: bool = False
    factor_grid: List[float] = field(default_factory=list)
    factor_resamples: int = 200
    frame_fit: str = "precision"
    evaluation_epoch: str = "reference"
    subset_transits: str = "live"
    basic_angle_harmonics: int = 0

    def __post_init__(self):
        _check_reference_epoch("experiment.primary.reference_epoch", self.reference_epoch)
        _require(isinstance(self.basic_angle_harmonics, int) and 0 <= self.basic_angle_harmonics <= MAX_BASIC_ANGLE_HARMONICS,
                 "experiment.primary.basic_angle_harmonics", self.basic_angle_harmonics,
                 f"an integer 0 (no calibration unknowns) to {MAX_BASIC_ANGLE_HARMONICS} (harmonics of the spin phase)")
        _require(self.evaluation_epoch in ("reference", "star_mean"), "experiment.primary.evaluation_epoch",
                 self.evaluation_epoch, "'reference' (the solution's epoch) or 'star_mean' (each star's mean "
                 "epoch of its transits)")
        _require(self.subset_transits in ("live", "scheduled"), "experiment.primary.subset_transits",
                 self.subset_transits, "'live' (FoV transits observed, after the dead time) or 'scheduled' "
                 "(FoV transits of the scanning law, before it)")
        _require(all(math.isfinite(k) and k > 0 for k in self.factor_grid)
                 and len(set(self.factor_grid)) == len(self.factor_grid),
                 "experiment.primary.factor_grid", list(self.factor_grid),
                 "distinct positive factors k of sigma_F90 (empty: no factor search)")
        _require(self.knot_transits is None or (math.isfinite(self.knot_transits) and self.knot_transits >= 1),
                 "experiment.primary.knot_transits", self.knot_transits,
                 "null (use knot_interval_hours) or a number of FoV transits per knot interval >= 1")
        _require(self.knot_rule in KNOT_RULES, "experiment.primary.knot_rule", self.knot_rule,
                 "'counts' (knot_transits FoV transits in every knot interval) or 'uniform' (knots at the "
                 "mean interval of knot_transits transits, as AGIS's uniform 30 s knots, longer where fewer fall)")
        _require(self.frame_fit in ("precision", "equal"), "experiment.primary.frame_fit", self.frame_fit,
                 "'precision' (the frame rotator weighted by formal precision) or 'equal'")
        _require(self.factor_resamples >= 0, "experiment.primary.factor_resamples", self.factor_resamples,
                 "a number of bootstrap resamples >= 0")
        _require(self.solver_start in ("previous", "zero"), "experiment.primary.solver_start", self.solver_start,
                 "'previous' (each solution after the first starts from the attitude of the one before) or "
                 "'zero' (every solution from the scanning law)")
        _require(self.solver_error_tol is None or (math.isfinite(self.solver_error_tol) and self.solver_error_tol > 0),
                 "experiment.primary.solver_error_tol", self.solver_error_tol,
                 "a positive fraction of the formal uncertainties, or null (stop on solver_rtol and "
                 "solver_update_tol_uas)")
        for key in ("class_size", "solver_max_iter"):
            _require(getattr(self, key) > 0, f"experiment.primary.{key}", getattr(self, key), "a positive number")
        _require(self.primary_sources >= 0, "experiment.primary.primary_sources", self.primary_sources,
                 "a number >= 0 (0: the magnitude classes only, as the paper)")
        _require(len(self.g_classes) > 0 and all(0 <= g < G_MAX for g in self.g_classes),
                 "experiment.primary.g_classes", list(self.g_classes), f"G values within 0..{G_MAX:g}")
        _require(0 <= self.dead_time_fraction < 1, "experiment.primary.dead_time_fraction",
                 self.dead_time_fraction, "a fraction in [0, 1)")
        _require(0 < self.mission_years <= 10, "experiment.primary.mission_years", self.mission_years,
                 "a length in (0, 10] years")
        for key in ("dead_time_block_days", "knot_interval_hours", "attitude_timescale_hours", "solver_rtol",
                    "solver_update_tol_uas"):
            v = getattr(self, key)
            _require(v > 0 and math.isfinite(v), f"experiment.primary.{key}", v, "a positive finite number")
        _require(self.attitude_amplitude_mas >= 0 and math.isfinite(self.attitude_amplitude_mas),
                 "experiment.primary.attitude_amplitude_mas", self.attitude_amplitude_mas,
                 "a non-negative finite angle in mas")


@dataclass
class ExperimentConf:
    #: 'f90_sweep' (Sect. 3, main job), 'secondary' (Sect. 4.1), 'primary' (Sect. 4.2) or
    #: 'real_sky' (Hipparcos stars as truth).
    name: str = "f90_sweep"
    showcase: ShowcaseConf = field(default_factory=ShowcaseConf)
    secondary: SecondaryConf = field(default_factory=SecondaryConf)
    primary: PrimaryConf = field(default_factory=PrimaryConf)
    real_sky: RealSkyConf = field(default_factory=RealSkyConf)

    def __post_init__(self):
        _require(self.name in ("f90_sweep", "secondary", "primary", "real_sky"), "experiment", self.name,
                 "'f90_sweep', 'secondary', 'primary' or 'real_sky'")


@dataclass
class PriorMapsConf:
    """HEALPix maps of the fitted prior written with every sweep (``prior_maps.fits``)."""

    #: HEALPix resolution of the maps (galactic, RING): a power of two.
    nside: int = 16

    def __post_init__(self):
        _require(isinstance(self.nside, int) and 1 <= self.nside <= MAX_NSIDE
                 and (self.nside & (self.nside - 1)) == 0,
                 "prior_maps.nside", self.nside, f"a power of two from 1 to {MAX_NSIDE}")


@dataclass
class ExecutionConf:
    #: joblib backend: 'loky' (processes), 'threading', 'sequential' or 'dask'.
    backend: str = "loky"
    n_jobs: int = 2
    #: Dask scheduler address (tcp://host:port); None starts a local cluster.
    scheduler_address: Optional[str] = None
    #: Show a progress bar.
    progress: bool = True
    #: Stars per task of the whole-sky experiments (memory per worker; results do not
    #: depend on it, so it is not part of the config hash).
    chunk_stars: int = 50_000

    def __post_init__(self):
        _require(self.backend in ("loky", "threading", "sequential", "dask"), "execution.backend",
                 self.backend, "'loky', 'threading', 'sequential' or 'dask'")
        _require(self.n_jobs >= 1, "execution.n_jobs", self.n_jobs, "a positive number of workers")
        _require(self.chunk_stars > 0, "execution.chunk_stars", self.chunk_stars, "a positive number of stars")


@dataclass
class ResumeConf:
    #: Keep finished cells written by another mcsweep version when resuming a run
    #: (default: refuse them, naming both versions). Not part of the config hash.
    accept_other_versions: bool = False


@dataclass
class Config:
    sky: SkyConf = field(default_factory=SkyConf)
    magnitudes: MagnitudesConf = field(default_factory=MagnitudesConf)
    prior_grid: PriorGridConf = field(default_factory=PriorGridConf)
    observations: ObservationsConf = field(default_factory=ObservationsConf)
    noise: NoiseConf = field(default_factory=NoiseConf)
    population: PopulationConf = field(default_factory=PopulationConf)
    scanning: ScanningConf = field(default_factory=ScanningConf)
    cell: CellConf = field(default_factory=CellConf)
    experiment: ExperimentConf = field(default_factory=ExperimentConf)
    execution: ExecutionConf = field(default_factory=ExecutionConf)
    resume: ResumeConf = field(default_factory=ResumeConf)
    prior_maps: PriorMapsConf = field(default_factory=PriorMapsConf)
    #: Master seed; every cell derives its own stream from (seed, cell identity).
    seed: int = 20150821
    #: Confidence level P of the ellipses (Sect. 2.4: 0.9).
    confidence: float = 0.9
    #: R = sigma_mu_p / sigma_plx_p in 1/yr (Eq. 18: 10 /yr).
    ratio_R: float = 10.0

    def __post_init__(self):
        _require(0.0 < self.confidence < 1.0 and math.isfinite(self.confidence), "confidence",
                 self.confidence, "a probability strictly between 0 and 1")
        _require(self.ratio_R > 0 and math.isfinite(self.ratio_R), "ratio_R", self.ratio_R,
                 "a positive, finite ratio in 1/yr")
        _require(self.seed >= 0, "seed", self.seed, "a non-negative integer")


#: Config keys (dotted, a whole group or one key) each experiment never reads. They are
#: left out of the config hash (:func:`mcsweep.sweep.provenance.config_hash`), and a
#: command line setting them gets a one-line warning (:func:`mcsweep.sweep.validate.ignored_settings`).
#: ``observations.reference_epoch`` is not listed: the global experiments take their
#: reference epoch from the config (a mean epoch of observation, paper Sect. 2.1, or a date).
IGNORED_BY_EXPERIMENT: Dict[str, tuple] = {
    # experiment.primary (added later) is ignored by the others so their config hashes stay as they were.
    # experiment.real_sky likewise (added after primary).
    "f90_sweep": ("experiment.primary", "experiment.real_sky"),
    # observations.start/end are read by the global experiments under a release preset
    # (observations=dr1..dr5 sets their mission), so they stay in the hash.
    "secondary": ("sky", "magnitudes", "prior_grid", "cell", "experiment.showcase", "experiment.primary",
                  "experiment.real_sky",
                  "observations.cases",
                  "observations.f90_case",
                  "observations.fixed_epoch", "prior_maps"),
    "primary": ("sky", "magnitudes", "prior_grid", "cell", "experiment.showcase", "experiment.secondary",
                "experiment.real_sky", "observations.cases", "observations.f90_case",
                "observations.fixed_epoch", "prior_maps"),
    "real_sky": ("sky", "magnitudes", "prior_grid", "cell", "population", "experiment.showcase",
                 "experiment.secondary", "experiment.primary", "observations.f90_case", "prior_maps"),
}


def register_configs() -> None:
    """Register the schema so ``conf/config.yaml`` can name ``base_config`` first."""
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=Config)
