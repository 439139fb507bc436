"""What every global experiment is given: mission, scanning law, noise, priors, epoch, seeds.

The global experiments (the secondary solution of paper Sect. 4.1, the primary solution
of Sect. 4.2, and the real-sky validation with Hipparcos stars, :mod:`.real_sky`) observe
whole-sky classes of stars over a mission interval with one scanning law and one noise
model, refer the astrometry to one reference epoch (Sect. 2.1,
:mod:`mcsweep.experiments.global_solution.epoch`), and set priors from sigma_F90 (Eqs. 14-17 or a sweep's
fitted coefficients) with R = sigma_mu / sigma_plx (Eq. 18). :class:`GlobalSettings` holds
exactly that; an experiment's own settings subclass it with what is specific to it, and
:func:`global_fields` reads the shared part of the experiment's config section
(``experiment.<name>``).

Every random stream of an experiment is ``SeedSequence(seed, spawn_key=(tag, stream,
...))`` with the experiment's ``tag`` (41 for Sect. 4.1, 42 for Sect. 4.2), so no two
experiments or streams share a generator and nothing depends on chunking.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ...astrometry.noise_models import NoiseModelLike, noise_model
from ...errors import UserInputError
from ...prior import G_FIT_MAX, sigma_f90, sigma_from_coefficients
from ...prior.run_record import COEFFICIENTS_FILE, read_coefficients
from ...scanning import ScanningLaw
from ...scanning.ephemeris import TABLE_END_JD_TCB, TABLE_START_JD_TCB
from ...scanning.segments import DATA_RELEASE_SPANS
from ...scanning.timescale import tcb_jd
from .epoch import describe_reference_epoch, resolve_reference_epoch

__all__ = ["GlobalSettings", "global_fields", "mission_span_jd", "load_f90_coefficients", "spawn"]


def spawn(seed: int, tag: int, stream: int, *key: int) -> np.random.SeedSequence:
    """The seed of one random stream of an experiment (module notes)."""
    return np.random.SeedSequence(seed, spawn_key=(tag, stream, *key))


@dataclasses.dataclass(frozen=True, kw_only=True)
class GlobalSettings:
    """The shared part of a global experiment's settings (picklable, sent to every task)."""

    seed: int
    start_jd: float
    end_jd: float
    law: ScanningLaw
    noise: NoiseModelLike
    confidence: float
    ratio_R: float
    #: Coefficients of Eqs. 15-17 as ((name, (c0, c1, ...)), ...); None = the paper's.
    f90_coefficients: tuple | None = None
    #: Reference epoch setting (:func:`~mcsweep.experiments.global_solution.epoch.resolve_reference_epoch`).
    reference_epoch: str = "dataset_mean"

    def epoch_tcb_jd(self, tcb_jd=None, mask=None) -> np.ndarray:
        """Reference epoch (TCB JD) of each star of ``tcb_jd (n, k)`` (one value without it)."""
        return resolve_reference_epoch(self.reference_epoch, self.start_jd, self.end_jd, tcb_jd, mask)

    @property
    def t_ref_jd(self) -> float:
        """The one reference epoch of a global solution (not defined for ``star_mean``)."""
        return float(np.ravel(self.epoch_tcb_jd())[0])

    def describe_epoch(self) -> dict:
        """What the epoch setting resolves to, for provenance (``derived``) and the report."""
        return describe_reference_epoch(self.reference_epoch, self.start_jd, self.end_jd)

    def sigma_f90_mas(self, l_deg, b_deg, g) -> np.ndarray:
        """The sigma_F90 prior of each star [mas] (G > 20 uses G = 20, as the paper says)."""
        if self.f90_coefficients is None:
            return sigma_f90(l_deg, b_deg, g)
        return sigma_from_coefficients(l_deg, b_deg, g, dict(self.f90_coefficients), g_max=G_FIT_MAX)


def load_f90_coefficients(spec: str, key: str = "experiment.secondary.f90_formula") -> tuple | None:
    """None for ``'paper'``; else the fitted coefficients of a sweep's ``coefficients.csv``.

    ``spec`` is the CSV file or the run directory holding it (columns ``term``, ``fitted``;
    terms ``s0_c0`` ... as written by :mod:`mcsweep.report.build`); ``key`` names the
    setting in error messages.
    """
    if spec == "paper":
        return None
    path = Path(spec)
    if path.is_dir():
        path = path / COEFFICIENTS_FILE
    if not path.is_file():
        raise UserInputError(f"{key}={spec!r} is not accepted; expected 'paper' or a sweep run's "
                             f"{COEFFICIENTS_FILE} (or its run directory)")
    try:
        coeffs = tuple(read_coefficients(path).items())
    except UserInputError as exc:
        raise UserInputError(f"{key}={spec!r} is not accepted: {exc}") from None
    if not all(np.isfinite(c).all() for _, c in coeffs):
        raise UserInputError(f"{key}={spec!r} is not accepted; its fitted coefficients are not all finite "
                             "(the sweep could not fit Eqs. 15-17)")
    return coeffs


def mission_span_jd(config, name: str) -> tuple[float, float]:
    """``[start, end)`` (TCB JD) of global experiment ``name``'s mission: a release preset's
    span (``observations=dr1..dr5``, which replaces ``mission_start`` / ``mission_years``),
    else ``experiment.<name>.mission_start`` plus ``mission_years`` Julian years."""
    section = getattr(config.experiment, name)
    obs = getattr(config, "observations", None)
    if obs is not None and obs.name in DATA_RELEASE_SPANS:
        return tcb_jd(str(obs.start), "observations.start"), tcb_jd(str(obs.end), "observations.end")
    start_jd = tcb_jd(str(section.mission_start), f"experiment.{name}.mission_start")
    return start_jd, start_jd + 365.25 * section.mission_years


def global_fields(config, name: str) -> dict:
    """The :class:`GlobalSettings` fields from a checked config's ``experiment.<name>``
    section (``mission_start``, ``mission_years``, ``f90_formula``, ``reference_epoch``)
    and the run's seed, scanning law, noise model, P and R; user errors raised here."""
    section = getattr(config.experiment, name)
    start_jd, end_jd = mission_span_jd(config, name)
    if start_jd < TABLE_START_JD_TCB + 1.0 or end_jd > TABLE_END_JD_TCB - 1.0:
        raise UserInputError(f"experiment.{name}.mission_start={section.mission_start!r} with mission_years="
                             f"{section.mission_years:g} is not accepted; expected a mission within 2013-2031 "
                             "(the observer ephemeris)")
    return dict(seed=int(config.seed), start_jd=start_jd, end_jd=end_jd,
                law=ScanningLaw.from_config(dataclasses.asdict(config.scanning)),
                noise=noise_model(config.noise),
                confidence=float(config.confidence), ratio_R=float(config.ratio_R),
                f90_coefficients=load_f90_coefficients(section.f90_formula, f"experiment.{name}.f90_formula"),
                reference_epoch=str(section.reference_epoch))
