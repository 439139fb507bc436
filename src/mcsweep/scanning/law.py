"""The scanning-law parameters, as one frozen dataclass that mirrors ``conf/scanning/*.yaml``.

The paper (Sect. 3.1) simulates Gaia's Nominal Scanning Law (NSL; de Bruijne et al.
2010, IAU Symp. 261, 331) "with initial precession and scan phase conditions
consistent with the real mission from October 2014 until the end of 2015". The
default values below are the *flown* law: the NSL with its constants fitted to the
real mission's scan history, valid from the re-phasing on 2014-09-25 to at least
2017-01-27 and extrapolated for any simulated interval. The design values
(S = 4.22, 60 arcsec/s) are the ``nominal`` preset.

Every number is a config value (``conf/scanning/flown.yaml``, ``nominal.yaml``), so
another law is a config change.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from functools import cached_property
from importlib import resources

from ..errors import UserInputError
from .timescale import tcb_jd

__all__ = ["ScanningLaw", "ARCSEC_PER_RAD", "SECONDS_PER_DAY"]

#: Arcseconds per radian.
ARCSEC_PER_RAD = 180.0 * 3600.0 / math.pi
#: Seconds per day.
SECONDS_PER_DAY = 86400.0


@dataclass(frozen=True, kw_only=True)
class ScanningLaw:
    """Parameters of a nominal-type scanning law (heliotropic angles xi, nu, Omega).

    Attributes
    ----------
    name : str
        Label of the law (``'flown'``, ``'nominal'``, ...); informational only.
    spin_rate_arcsec_s : float
        Inertial spin rate omega_z about the spin axis [arcsec/s].
    solar_aspect_deg : float
        Solar aspect angle xi, between the spin axis and the nominal Sun [deg].
    precession_S : float
        Precession speed constant S (dimensionless): the spin axis precesses
        S revolutions per year relative to the Sun, to first order.
    ref_epoch_tcb : str
        ISO epoch (TCB) at which the phases below apply.
    nu_ref_deg : float
        Precession phase nu at ``ref_epoch_tcb`` [deg].
    omega_ref_deg : float
        Spin phase Omega at ``ref_epoch_tcb`` [deg].
    basic_angle_deg : float
        Basic angle Gamma between the two fields of view [deg]; the preceding FoV is at
        azimuth +Gamma/2 in the scan plane, the following at -Gamma/2.
    ac_limits_p_deg, ac_limits_f_deg : tuple of float
        Accepted across-scan offsets ``(low, high)`` of a star from the scan plane,
        ``zeta = asin(u . z)``, in the preceding and following FoV [deg].
    """

    # Provenance. spin_rate_arcsec_s, precession_S, nu_ref_deg and omega_ref_deg were
    # fitted to Gaia's observation forecasts from GOST (the Gaia Observation Forecast
    # Tool, ESA, https://gaia.esac.esa.int/gost/) for 2014-09-25 (end of the re-phasing)
    # to 2017-01-27: residuals 0.5 s (median) in transit time and 0.002 deg in scan
    # angle. Their design values, 60 arcsec/s and S = 4.22, are those of de Bruijne et
    # al. (2010) and Gaia Collaboration, Prusti et al. (2016, A&A 595, A1), who also give
    # the solar aspect angle xi = 45 deg and the basic angle Gamma = 106.5 deg. The
    # across-scan acceptance spans 0.695 deg, the across-scan size of the astrometric
    # field (about 0.7 deg, Prusti et al. 2016); the origin of its offset from the scan
    # plane (mirrored between the FoVs) is not documented in this repository.
    name: str = "flown"
    spin_rate_arcsec_s: float = 59.960499
    solar_aspect_deg: float = 45.0
    precession_S: float = 4.220747
    ref_epoch_tcb: str = "2015-01-01T00:00:00"
    nu_ref_deg: float = 323.3708
    omega_ref_deg: float = 95.1324
    basic_angle_deg: float = 106.5
    ac_limits_p_deg: tuple[float, float] = (-0.41, 0.285)
    ac_limits_f_deg: tuple[float, float] = (-0.285, 0.41)

    def __post_init__(self):
        # Normalise sequences from YAML/OmegaConf to tuples so the law stays hashable.
        for key in ("ac_limits_p_deg", "ac_limits_f_deg"):
            value = getattr(self, key)
            try:
                pair = tuple(float(v) for v in value)
            except TypeError:
                raise UserInputError(f"scanning.{key}={value!r} is not accepted; expected [low, high] in deg")
            if len(pair) != 2 or not (-5.0 < pair[0] < pair[1] < 5.0):
                raise UserInputError(
                    f"scanning.{key}={list(pair)!r} is not accepted; expected [low, high] in deg "
                    "with -5 < low < high < 5"
                )
            object.__setattr__(self, key, pair)
        for key in ("spin_rate_arcsec_s", "solar_aspect_deg", "precession_S", "nu_ref_deg",
                    "omega_ref_deg", "basic_angle_deg"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise UserInputError(f"scanning.{key}={value!r} is not accepted; expected a finite number")
            object.__setattr__(self, key, float(value))
        if not 0.0 < self.spin_rate_arcsec_s <= 3600.0:
            raise UserInputError(
                f"scanning.spin_rate_arcsec_s={self.spin_rate_arcsec_s!r} is not accepted; "
                "expected a rate in (0, 3600] arcsec/s"
            )
        if not 0.0 < self.solar_aspect_deg < 90.0:
            raise UserInputError(
                f"scanning.solar_aspect_deg={self.solar_aspect_deg!r} is not accepted; expected (0, 90) deg"
            )
        if not self.precession_S > 1.0:
            raise UserInputError(
                f"scanning.precession_S={self.precession_S!r} is not accepted; expected S > 1 "
                "(the NSL needs S > |cos nu|)"
            )
        if not 0.0 < self.basic_angle_deg < 180.0:
            raise UserInputError(
                f"scanning.basic_angle_deg={self.basic_angle_deg!r} is not accepted; expected (0, 180) deg"
            )
        if not isinstance(self.ref_epoch_tcb, str):
            raise UserInputError(f"scanning.ref_epoch_tcb={self.ref_epoch_tcb!r} is not accepted; "
                                 "expected an ISO date such as '2015-01-01T00:00:00'")
        tcb_jd(self.ref_epoch_tcb, "scanning.ref_epoch_tcb")

    # ------------------------------------------------------------------ derived values
    @cached_property
    def ref_epoch_jd(self) -> float:
        """Reference epoch as a Julian date in TCB [day]."""
        return tcb_jd(self.ref_epoch_tcb, "scanning.ref_epoch_tcb")

    @property
    def spin_rate_rad_day(self) -> float:
        """omega_z [rad/day]."""
        return self.spin_rate_arcsec_s * SECONDS_PER_DAY / ARCSEC_PER_RAD

    @property
    def spin_period_days(self) -> float:
        """Inertial spin period 2 pi / omega_z [day] (about 6 h)."""
        return 2.0 * math.pi / self.spin_rate_rad_day

    @property
    def fov_lag_days(self) -> float:
        """Time a star takes from the preceding to the following FoV, Gamma / omega_z [day]."""
        return math.radians(self.basic_angle_deg) / self.spin_rate_rad_day

    @property
    def max_abs_ac_deg(self) -> float:
        """Largest accepted |zeta| of either FoV [deg]."""
        return max(abs(v) for v in self.ac_limits_p_deg + self.ac_limits_f_deg)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_config(cls, mapping: Mapping) -> "ScanningLaw":
        """Build a law from a config mapping (plain dict or OmegaConf node).

        Keys are the field names; missing keys take the defaults (the flown law).

        Raises
        ------
        mcsweep.errors.UserInputError
            On an unknown key or an unacceptable value.
        """
        try:
            from omegaconf import DictConfig, OmegaConf

            if isinstance(mapping, DictConfig):
                mapping = OmegaConf.to_container(mapping, resolve=True)
        except ImportError:  # pragma: no cover - omegaconf is a dependency
            pass
        if not isinstance(mapping, Mapping):
            raise UserInputError(f"scanning config {mapping!r} is not accepted; expected a mapping of keys")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(mapping) - known)
        if unknown:
            raise UserInputError(
                f"scanning config keys {unknown} are not accepted; expected some of {sorted(known)}"
            )
        return cls(**dict(mapping))

    @classmethod
    def preset(cls, name: str) -> "ScanningLaw":
        """The law shipped as ``conf/scanning/<name>.yaml`` (``'flown'`` or ``'nominal'``)."""
        import yaml

        folder = resources.files("mcsweep.conf").joinpath("scanning")
        available = sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))
        if name not in available:
            raise UserInputError(f"scanning law {name!r} is not accepted; expected one of {available}")
        with folder.joinpath(f"{name}.yaml").open("r", encoding="utf-8") as fh:
            return cls.from_config(yaml.safe_load(fh))
