"""The real-sky validation's config section, ``experiment.real_sky``."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List

from ..config_checks import require


@dataclass
class RealSkyConf:
    """Real-sky validation with Hipparcos stars as truth; documented in
    conf/experiment/real_sky.yaml and :mod:`mcsweep.experiments.real_sky.experiment`."""

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
    #: Sweep run directories made with ``prior_model=colour`` or ``colour_mean``: one more
    #: prior each, queried with each star's Gaia BP-RP (and centred on the run's mean).
    colour_priors: List[str] = field(default_factory=list)

    def __post_init__(self):
        require(0 <= self.g_min < self.g_max <= 21, "experiment.real_sky.g_min/g_max", (self.g_min, self.g_max),
                 "0 <= g_min < g_max <= 21")
        require(len(self.cases) > 0 and len(set(self.cases)) == len(self.cases), "experiment.real_sky.cases",
                 list(self.cases), "a non-empty list of distinct observation case names")
        require(self.max_stars >= 0, "experiment.real_sky.max_stars", self.max_stars,
                 "0 (all stars) or a positive number of stars")
        require(self.factor > 0 and math.isfinite(self.factor), "experiment.real_sky.factor", self.factor,
                 "a positive, finite multiplier")
        require(len(set(map(str, self.colour_priors))) == len(self.colour_priors), "experiment.real_sky.colour_priors",
                 list(self.colour_priors), "a list of distinct sweep run directories")
