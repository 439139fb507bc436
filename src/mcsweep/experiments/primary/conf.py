"""The primary solution's config section, ``experiment.primary`` (paper Sect. 4.2, Table 3)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional

from ...astrometry.noise import G_MAX
from ..config_checks import check_reference_epoch, require


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
    conf/experiment/primary.yaml and :mod:`mcsweep.experiments.primary.experiment`."""

    class_size: int = 30000
    g_classes: List[float] = field(default_factory=lambda: [11.0, 15.0, 19.0])
    extra_sources: int = 0
    extra_g_min: float = 13.0
    mission_years: float = 1.0
    mission_start: str = "2014-07-25T10:30:00"
    dead_time_fraction: float = 0.2
    dead_time_outage_days: float = 0.25
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
        check_reference_epoch("experiment.primary.reference_epoch", self.reference_epoch)
        require(isinstance(self.basic_angle_harmonics, int) and 0 <= self.basic_angle_harmonics <= MAX_BASIC_ANGLE_HARMONICS,
                 "experiment.primary.basic_angle_harmonics", self.basic_angle_harmonics,
                 f"an integer 0 (no calibration unknowns) to {MAX_BASIC_ANGLE_HARMONICS} (harmonics of the spin phase)")
        require(self.evaluation_epoch in ("reference", "star_mean"), "experiment.primary.evaluation_epoch",
                 self.evaluation_epoch, "'reference' (the solution's epoch) or 'star_mean' (each star's mean "
                 "epoch of its transits)")
        require(self.subset_transits in ("live", "scheduled"), "experiment.primary.subset_transits",
                 self.subset_transits, "'live' (FoV transits observed, after the dead time) or 'scheduled' "
                 "(FoV transits of the scanning law, before it)")
        require(all(math.isfinite(k) and k > 0 for k in self.factor_grid)
                 and len(set(self.factor_grid)) == len(self.factor_grid),
                 "experiment.primary.factor_grid", list(self.factor_grid),
                 "distinct positive factors k of sigma_F90 (empty: no factor search)")
        require(self.knot_transits is None or (math.isfinite(self.knot_transits) and self.knot_transits >= 1),
                 "experiment.primary.knot_transits", self.knot_transits,
                 "null (use knot_interval_hours) or a number of FoV transits per knot interval >= 1")
        require(self.knot_rule in KNOT_RULES, "experiment.primary.knot_rule", self.knot_rule,
                 "'counts' (knot_transits FoV transits in every knot interval) or 'uniform' (knots at the "
                 "mean interval of knot_transits transits, as AGIS's uniform 30 s knots, longer where fewer fall)")
        require(self.frame_fit in ("precision", "equal"), "experiment.primary.frame_fit", self.frame_fit,
                 "'precision' (the frame rotator weighted by formal precision) or 'equal'")
        require(self.factor_resamples >= 0, "experiment.primary.factor_resamples", self.factor_resamples,
                 "a number of bootstrap resamples >= 0")
        require(self.solver_start in ("previous", "zero"), "experiment.primary.solver_start", self.solver_start,
                 "'previous' (each solution after the first starts from the attitude of the one before) or "
                 "'zero' (every solution from the scanning law)")
        require(self.solver_error_tol is None or (math.isfinite(self.solver_error_tol) and self.solver_error_tol > 0),
                 "experiment.primary.solver_error_tol", self.solver_error_tol,
                 "a positive fraction of the formal uncertainties, or null (stop on solver_rtol and "
                 "solver_update_tol_uas)")
        for key in ("class_size", "solver_max_iter"):
            require(getattr(self, key) > 0, f"experiment.primary.{key}", getattr(self, key), "a positive number")
        require(self.extra_sources >= 0, "experiment.primary.extra_sources", self.extra_sources,
                 "a number >= 0 (0: the magnitude classes only, as the paper)")
        require(len(self.g_classes) > 0 and all(0 <= g < G_MAX for g in self.g_classes),
                 "experiment.primary.g_classes", list(self.g_classes), f"G values within 0..{G_MAX:g}")
        require(0 <= self.dead_time_fraction < 1, "experiment.primary.dead_time_fraction",
                 self.dead_time_fraction, "a fraction in [0, 1)")
        require(0 < self.mission_years <= 10, "experiment.primary.mission_years", self.mission_years,
                 "a length in (0, 10] years")
        for key in ("dead_time_outage_days", "knot_interval_hours", "attitude_timescale_hours", "solver_rtol",
                    "solver_update_tol_uas"):
            v = getattr(self, key)
            require(v > 0 and math.isfinite(v), f"experiment.primary.{key}", v, "a positive finite number")
        require(self.attitude_amplitude_mas >= 0 and math.isfinite(self.attitude_amplitude_mas),
                 "experiment.primary.attitude_amplitude_mas", self.attitude_amplitude_mas,
                 "a non-negative finite angle in mas")
