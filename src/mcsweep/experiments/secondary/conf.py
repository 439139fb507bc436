"""The secondary solution's config section, ``experiment.secondary`` (paper Sect. 4.1)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List

from ...astrometry.noise import G_MAX
from ..config_checks import check_reference_epoch, require


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
        check_reference_epoch("experiment.secondary.reference_epoch", self.reference_epoch)
        require(self.class_size > 0, "experiment.secondary.class_size", self.class_size, "a positive number")
        require(len(self.g_classes) > 0 and all(0 <= g < G_MAX for g in self.g_classes),
                 "experiment.secondary.g_classes", list(self.g_classes), f"G values within 0..{G_MAX:g}")
        require(0 <= self.dilution < 1, "experiment.secondary.dilution", self.dilution, "a probability in [0, 1)")
        require(0 < self.mission_years <= 10, "experiment.secondary.mission_years", self.mission_years,
                 "a length in (0, 10] years")
