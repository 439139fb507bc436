"""The scanning-law parameters, as one frozen dataclass that mirrors ``conf/scanning/*.yaml``.

The paper (Sect. 3.1) simulates Gaia's Nominal Scanning Law (NSL; de Bruijne et al.
2010, IAU Symp. 261, 331) "with initial precession and scan phase conditions
consistent with the real mission from October 2014 until the end of 2015". The
default values below are the *flown* law: a sequence of segments
(:mod:`mcsweep.scanning.segments`) fitted to Gaia's real scan history from the start of
routine operations (2014-07-25T10:30 TCB) to the end of science operations
(2025-01-15), extrapolated outside that span. The design values (S = 4.22, 60 arcsec/s)
with one set of phases are the ``nominal`` preset (one NSL segment, extrapolated
everywhere).

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
from .segments import FLOWN_SEGMENTS, Segment, segments_from_config
from .timescale import tcb_jd

__all__ = ["ScanningLaw", "ARCSEC_PER_RAD", "SECONDS_PER_DAY"]

_PHASE_KEYS = ("ref_epoch_tcb", "nu_ref_deg", "omega_ref_deg")

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
    ref_epoch_tcb : str or None
        ISO epoch (TCB) at which the phases below apply: a law of one NSL segment without
        bounds (``nominal``). None when ``segments`` are given.
    nu_ref_deg : float or None
        Precession phase nu at ``ref_epoch_tcb`` [deg].
    omega_ref_deg : float or None
        Spin phase Omega at ``ref_epoch_tcb`` [deg].
    segments : tuple of Segment
        The law as a sequence of segments, each with its kind and phases
        (:mod:`mcsweep.scanning.segments`); empty when the three phases above are given.
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
    # The flown law's phases are per segment (mcsweep.scanning.segments.FLOWN_SEGMENTS);
    # its 2014-09-25 - 2017-01-27 segment holds the values fitted when the flown law was a
    # single NSL segment (2015-01-01: nu = 323.3708 deg, Omega = 95.1324 deg).
    ref_epoch_tcb: str | None = None
    nu_ref_deg: float | None = None
    omega_ref_deg: float | None = None
    basic_angle_deg: float = 106.5
    ac_limits_p_deg: tuple[float, float] = (-0.41, 0.285)
    ac_limits_f_deg: tuple[float, float] = (-0.285, 0.41)
    segments: tuple[Segment, ...] = FLOWN_SEGMENTS

    def __post_init__(self):
        object.__setattr__(self, "segments", segments_from_config(self.segments))
        given = [k for k in _PHASE_KEYS if getattr(self, k) is not None]
        if self.segments and given:
            raise UserInputError(
                f"scanning.{given[0]}={getattr(self, given[0])!r} is not accepted together with scanning.segments; "
                "expected null phases (each segment has its own) or segments: [] (one NSL segment)")
        if not self.segments and len(given) != len(_PHASE_KEYS):
            missing = [k for k in _PHASE_KEYS if k not in given]
            raise UserInputError(
                f"scanning.{missing[0]}=None is not accepted without scanning.segments; expected "
                "ref_epoch_tcb, nu_ref_deg and omega_ref_deg (one NSL segment) or a list of segments")
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
            if value is None and key in _PHASE_KEYS:
                continue
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
        if self.segments:
            return
        if not isinstance(self.ref_epoch_tcb, str):
            raise UserInputError(f"scanning.ref_epoch_tcb={self.ref_epoch_tcb!r} is not accepted; "
                                 "expected an ISO date such as '2015-01-01T00:00:00'")
        tcb_jd(self.ref_epoch_tcb, "scanning.ref_epoch_tcb")

    # ------------------------------------------------------------------ derived values
    @cached_property
    def segment_list(self) -> tuple[Segment, ...]:
        """The segments the attitude is evaluated in: ``segments``, or one unbounded NSL
        segment from the top-level phases."""
        if self.segments:
            return self.segments
        return (Segment(kind="nsl", ref_epoch_tcb=self.ref_epoch_tcb, nu_ref_deg=self.nu_ref_deg,
                        omega_ref_deg=self.omega_ref_deg, key="scanning"),)

    @property
    def ref_epoch_jd(self) -> float:
        """Reference epoch of the top-level phases (one-segment law) as a TCB Julian date [day]."""
        return self.segment_list[0].ref_epoch_jd if not self.segments else math.nan

    def segment_labels(self, tcb_jd) -> list[str]:
        """Name of the segment holding each epoch (e.g. ``'nsl 2014-09-25..2017-01-27'``), with
        ``' (extrapolated)'`` outside the law's validity and ``'gap'`` between segments."""
        import numpy as np

        segs = self.segment_list
        starts = np.array([s.start_jd for s in segs])
        t = np.atleast_1d(np.asarray(tcb_jd, dtype=float))
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(segs) - 1)
        out = []
        for ti, ki in zip(t, k):
            seg = segs[ki]
            if seg.start_jd <= ti < seg.end_jd:
                out.append(seg.label())
            elif ki == 0 and ti < seg.start_jd or ki == len(segs) - 1 and ti >= seg.end_jd:
                out.append(seg.label() + " (extrapolated)")
            else:
                out.append("gap")
        if not self.segments:
            out = [f"{self.name} (extrapolated)" for _ in out]
        return out

    @property
    def validity_jd(self) -> tuple[float, float] | None:
        """``(start, end)`` (TCB JD) of the span the law was fitted to; None (``nominal``): nowhere."""
        if not self.segments:
            return None
        return self.segments[0].start_jd, self.segments[-1].end_jd

    def extrapolation_note(self, start_jd: float, end_jd: float) -> str | None:
        """One sentence when ``[start_jd, end_jd)`` reaches outside the law's validity, else None."""
        from .timescale import iso_tcb

        if self.validity_jd is None:
            return (f"scanning law '{self.name}' is one NSL with fixed phases, not fitted to Gaia's scan "
                    "history: the simulated scans are extrapolated (scanning=flown follows the mission "
                    "2014-07-25 - 2025-01-15)")
        lo, hi = self.validity_jd
        if start_jd >= lo and end_jd <= hi:
            return None
        return (f"scanning law '{self.name}' is extrapolated: the interval {iso_tcb(start_jd)} - "
                f"{iso_tcb(end_jd)} (TCB) reaches outside its validity {iso_tcb(lo)} - {iso_tcb(hi)}")

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
        ``segments`` is a list of mappings (:func:`~mcsweep.scanning.segments.segments_from_config`).

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
