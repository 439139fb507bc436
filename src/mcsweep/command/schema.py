"""Typed schemas of the configuration (Hydra structured configs).

The dataclasses are registered in Hydra's ConfigStore as ``base_config`` and named
first in ``conf/config.yaml``'s defaults list, so a value of the wrong type or an
unknown key fails at compose time. Ranges are checked in ``__post_init__``, which
runs when the composed config is turned into objects with
:func:`omegaconf.OmegaConf.to_object` (see :func:`mcsweep.command.validate.to_config`);
each check raises :class:`mcsweep.errors.UserInputError` with one line naming the key,
the value and what is accepted.

The sections of the experiments are their own (``experiments/<kind>/conf.py``); this module
puts them together with the sections every experiment shares.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

from hydra.core.config_store import ConfigStore

from ..astrometry.noise_models import noise_model
from ..experiments.config_checks import require, tcb_jd_checked
from ..experiments.f90_sweep.conf import CellConf, MagnitudesConf, PriorGridConf, PriorMapsConf, PriorModelConf, SkyConf
from ..experiments.registry import experiment_conf_class
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
    "ExperimentConf",
    "ExecutionConf",
    "ResumeConf",
    "Config",
    "register_configs",
]


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
        require(len(self.cases) > 0, "observations.cases", dict(self.cases), "at least one case")
        for k, v in self.cases.items():
            require(len(v) > 0, f"observations.cases.{k}", list(v), "a non-empty list of group indices")
        require(self.f90_case in self.cases, "observations.f90_case", self.f90_case,
                 f"one of the cases {sorted(self.cases)}")
        require(self.reference_epoch in ("mean", "fixed"), "observations.reference_epoch",
                 self.reference_epoch, "'mean' or 'fixed'")
        start, end = (tcb_jd_checked(f"observations.{k}", getattr(self, k)) for k in ("start", "end"))
        tcb_jd_checked("observations.fixed_epoch", self.fixed_epoch)
        require(end > start, "observations.end", self.end, f"a date after observations.start={self.start}")


@dataclass
class NoiseConf:
    """Per-FoV-transit measurement precision: the noise model ``model`` (a name of
    :data:`mcsweep.astrometry.noise_models.NOISE_MODELS`; the published one by default) with
    the settings below; the presets (``noise=gaia``, ``al_only``, ``edr3_floor``) are named
    sets of them."""

    #: The preset's name, recorded with the run (a label: the fields below set the model).
    name: str = "gaia"
    #: The noise model, by its registered name.
    model: str = "published"
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
        # the model's own checks, one place for them (mcsweep.astrometry.noise_models)
        noise_model(self)


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
        require(self.name in ("galaxy_model", "catalogue"), "population", self.name,
                 "'galaxy_model' or 'catalogue'")
        require(self.on_missing in ("error", "drop"), "population.on_missing", self.on_missing,
                 "'error' or 'drop'")
        if self.name == "catalogue":
            require(bool(self.path), "population.path", self.path, "the path of a catalogue file")


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


#: ``experiment``: its ``name`` (the kind) and one section per registered experiment
#: (:mod:`mcsweep.experiments.registry`).
ExperimentConf = experiment_conf_class()


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
        require(self.backend in ("loky", "threading", "sequential", "dask"), "execution.backend",
                 self.backend, "'loky', 'threading', 'sequential' or 'dask'")
        require(self.n_jobs >= 1, "execution.n_jobs", self.n_jobs, "a positive number of workers")
        require(self.chunk_stars > 0, "execution.chunk_stars", self.chunk_stars, "a positive number of stars")


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
    prior_model: PriorModelConf = field(default_factory=PriorModelConf)
    #: Master seed; every cell derives its own stream from (seed, cell identity).
    seed: int = 20150821
    #: Confidence level P of the ellipses (Sect. 2.4: 0.9).
    confidence: float = 0.9
    #: R = sigma_mu_p / sigma_plx_p in 1/yr (Eq. 18: 10 /yr).
    ratio_R: float = 10.0

    def __post_init__(self):
        require(0.0 < self.confidence < 1.0 and math.isfinite(self.confidence), "confidence",
                 self.confidence, "a probability strictly between 0 and 1")
        require(self.ratio_R > 0 and math.isfinite(self.ratio_R), "ratio_R", self.ratio_R,
                 "a positive, finite ratio in 1/yr")
        require(self.seed >= 0, "seed", self.seed, "a non-negative integer")


def register_configs() -> None:
    """Register the schema so ``conf/config.yaml`` can name ``base_config`` first."""
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=Config)
