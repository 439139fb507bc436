"""The real-epochs experiment's config section, ``experiment.real_epochs``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional

from ..config_checks import require
from ..global_solution.priors import parse_prior

__all__ = ["RealEpochsConf", "RESERVED_PRIORS", "MAX_K"]

#: Prior names the experiment gives itself: 'none' is the position-only solution (Table 2's
#: "none (2 parameters)"), 'fitted' the sweep run's fitted prior of ``fitted_prior``.
RESERVED_PRIORS = ("none", "fitted")
#: Largest subset size accepted: the vendored sample's sources have 26-54 visits and 49-177
#: FoV transits, and the experiment is about few observations (the paper's Table 2 splits at
#: 4 transits), so a larger k is a typing error rather than a question.
MAX_K = 50


def _sizes(values, key: str, unit: str) -> None:
    vals = list(values)
    require(all(isinstance(v, int) and 2 <= v <= MAX_K for v in vals) and len(set(vals)) == len(vals), key, vals,
            f"a list of distinct whole numbers of {unit} from 2 to {MAX_K} (one {unit[:-1]} has no 2-D position: "
            "along-scan measurements in one direction), or [] for none")


@dataclass
class RealEpochsConf:
    """Random subsets of real Gaia DR4 epoch astrometry solved with and without the prior;
    documented in conf/experiment/real_epochs.yaml and :mod:`mcsweep.experiments.real_epochs`."""

    #: Gaia DR4 epoch-astrometry file (archive or DPAC columns, any table format); None: the
    #: vendored sample (mcsweep/data/epoch_astrometry/sample_epoch_astrometry.parquet).
    epoch_file: Optional[str] = None
    #: Its sources table (source_id, ra, dec [deg], phot_g_mean_mag); None: the vendored
    #: sample's sample_sources.csv. Given together with epoch_file, or both left None.
    sources_file: Optional[str] = None
    #: Subset sizes in FoV transits (k transits drawn at random from each source's).
    transits: List[int] = field(default_factory=lambda: [2, 3, 4, 6])
    #: Subset sizes in visits (all transits of k visits drawn at random).
    visits: List[int] = field(default_factory=lambda: [2, 3, 4, 6])
    #: Random subsets per source, unit and k.
    draws: int = 200
    #: Priors solved with, in the grammar of Tables 2 and 3: '<k>F90' (k sigma_F90 of the
    #: paper, Eqs. 14-17) or '<sigma>mas' (one sigma for every star).
    priors: List[str] = field(default_factory=lambda: ["F90", "10F90", "1000mas"])
    #: A sigma_F90 sweep's run directory: one more prior, 'fitted' (Prior.from_run); None: none.
    fitted_prior: Optional[str] = None
    #: Resamples of the sources for the bootstrap intervals.
    bootstrap: int = 1000

    def __post_init__(self):
        for key in ("epoch_file", "sources_file", "fitted_prior"):
            value = getattr(self, key)
            require(value is None or (isinstance(value, str) and value.strip() != ""), f"experiment.real_epochs.{key}",
                    value, "null or a path" + (" (a sweep's run directory)" if key == "fitted_prior" else " of a file"))
        require((self.epoch_file is None) == (self.sources_file is None), "experiment.real_epochs.sources_file",
                self.sources_file, "a sources table together with epoch_file, or both null (the vendored sample): "
                "the sample's sources table describes the sample's sources only")
        _sizes(self.transits, "experiment.real_epochs.transits", "transits")
        _sizes(self.visits, "experiment.real_epochs.visits", "visits")
        require(len(self.transits) + len(self.visits) > 0, "experiment.real_epochs.visits", list(self.visits),
                "at least one subset size in transits or visits")
        require(isinstance(self.draws, int) and 1 <= self.draws <= 100_000, "experiment.real_epochs.draws", self.draws,
                "a whole number of random subsets per source, unit and k, from 1 to 100000")
        labels = [str(p) for p in self.priors]
        require(len(labels) > 0 and len(set(labels)) == len(labels), "experiment.real_epochs.priors", labels,
                "a non-empty list of distinct priors such as [F90, 10F90, 1000mas]")
        for p in labels:
            require(p not in RESERVED_PRIORS, "experiment.real_epochs.priors", labels,
                    "priors other than 'none' (always solved: position only) and 'fitted' (set fitted_prior)")
            parse_prior(p, "experiment.real_epochs.priors")
        require(isinstance(self.bootstrap, int) and 100 <= self.bootstrap <= 100_000,
                "experiment.real_epochs.bootstrap", self.bootstrap,
                "a whole number of resamples from 100 (a 16-84 % interval needs at least ~100) to 100000")
