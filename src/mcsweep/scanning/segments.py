"""The scanning law as a sequence of segments, each with its own law kind and phases.

Gaia did not fly one Nominal Scanning Law (NSL) from 2014 to 2025: it started routine
operations with the Ecliptic Pole Scanning Law (EPSL), was re-phased, had a gap in 2017
after which the spin phase was re-set, and precessed the other way round for a year.
A :class:`Segment` is one stretch ``[start, end)`` (TCB) of one law kind with its phases
at its own reference epoch; the time between two segments is a gap without transits.
Outside the first segment's start and the last one's end the law is *extrapolated*
(the first segment backwards, the last one forwards).

Law kinds (heliotropic angles as in :mod:`mcsweep.scanning.attitude`):

* ``nsl``: the NSL (de Bruijne et al. 2010),
  dnu/dt = lambda_s' (sqrt(S^2 - cos^2 nu) + cos xi sin nu) / sin xi;
* ``nsl_reversed``: the same equations with the negative root,
  dnu/dt = lambda_s' (-sqrt(S^2 - cos^2 nu) + cos xi sin nu) / sin xi < 0;
* ``epsl``: nu held fixed at ``nu_ref_deg`` (dnu/dt = 0); at nu = 180 deg the spin
  axis lies in the ecliptic and every scan passes the ecliptic poles.

For every kind dOmega/dt = omega_z - cos xi dnu/dt - sin xi sin nu lambda_s' (for the
EPSL at nu = 180 deg this is omega_z).

The flown sequence (:data:`FLOWN_SEGMENTS`, mirrored by ``conf/scanning/flown.yaml``)
is the research note ``scanning-law-history.md`` (project notes): the NSL in
mcsweep's conventions with S = 4.220747 and omega_z = 59.960499 arcsec/s throughout,
phases fitted per segment to ESA's Gaia Observation Forecast Tool (GOST,
https://gaia.esac.esa.int/gost/) predictions over random directions.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from functools import cached_property

from ..errors import UserInputError
from .timescale import tcb_jd

__all__ = ["Segment", "SEGMENT_KINDS", "FLOWN_SEGMENTS", "DATA_RELEASE_SPANS", "segments_from_config", "check_sequence"]

#: Law kinds of a segment and the sign of the square root in dnu/dt (0: nu held fixed).
SEGMENT_KINDS = {"nsl": 1.0, "nsl_reversed": -1.0, "epsl": 0.0}


@dataclass(frozen=True, kw_only=True)
class Segment:
    """One stretch of the scanning law.

    Attributes
    ----------
    kind : str
        ``'nsl'``, ``'nsl_reversed'`` or ``'epsl'`` (module notes).
    start_tcb, end_tcb : str or None
        ISO dates (TCB) of the segment ``[start, end)``; None = unbounded (only the single
        segment of a law given by top-level phases, e.g. ``nominal``).
    ref_epoch_tcb : str
        ISO epoch (TCB) at which the phases apply (need not lie inside the segment).
    nu_ref_deg, omega_ref_deg : float
        Precession phase nu and spin phase Omega at ``ref_epoch_tcb`` [deg].
    """

    kind: str = "nsl"
    start_tcb: str | None = None
    end_tcb: str | None = None
    ref_epoch_tcb: str
    nu_ref_deg: float
    omega_ref_deg: float
    #: Key prefix in error messages (not compared).
    key: str = field(default="scanning.segments", compare=False, repr=False)

    def __post_init__(self):
        key = self.key
        if self.kind not in SEGMENT_KINDS:
            raise UserInputError(f"{key}.kind={self.kind!r} is not accepted; expected one of {sorted(SEGMENT_KINDS)}")
        for name in ("nu_ref_deg", "omega_ref_deg"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise UserInputError(f"{key}.{name}={value!r} is not accepted; expected a finite number")
            object.__setattr__(self, name, float(value))
        for name in ("start_tcb", "end_tcb", "ref_epoch_tcb"):
            value = getattr(self, name)
            if value is None and name != "ref_epoch_tcb":
                continue
            if not isinstance(value, str):
                raise UserInputError(f"{key}.{name}={value!r} is not accepted; expected an ISO date (TCB) "
                                     "such as '2017-02-08T00:00:00'")
            tcb_jd(value, f"{key}.{name}")
        if not self.end_jd > self.start_jd:
            raise UserInputError(f"{key}.end_tcb={self.end_tcb!r} is not accepted; expected a date after "
                                 f"{key}.start_tcb={self.start_tcb!r}")

    def as_dict(self) -> dict:
        """The config mapping of this segment (the keys of ``conf/scanning/flown.yaml``)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "key"}

    @cached_property
    def start_jd(self) -> float:
        """Start (TCB JD); -inf when unbounded."""
        return -math.inf if self.start_tcb is None else tcb_jd(self.start_tcb, f"{self.key}.start_tcb")

    @cached_property
    def end_jd(self) -> float:
        """End (TCB JD, excluded); +inf when unbounded."""
        return math.inf if self.end_tcb is None else tcb_jd(self.end_tcb, f"{self.key}.end_tcb")

    @cached_property
    def ref_epoch_jd(self) -> float:
        """Reference epoch of the phases (TCB JD)."""
        return tcb_jd(self.ref_epoch_tcb, f"{self.key}.ref_epoch_tcb")

    @property
    def root_sign(self) -> float:
        """+1 (NSL), -1 (reversed precession) or 0 (EPSL: nu held fixed)."""
        return SEGMENT_KINDS[self.kind]

    def label(self) -> str:
        """Short human-readable name, e.g. ``'nsl 2017-02-08..2019-07-05'``."""
        lo = "" if self.start_tcb is None else self.start_tcb[:10]
        hi = "" if self.end_tcb is None else self.end_tcb[:10]
        return f"{self.kind} {lo}..{hi}"


def segments_from_config(value) -> tuple[Segment, ...]:
    """Segments from a config list of mappings (or Segments); checks the sequence.

    Raises
    ------
    mcsweep.errors.UserInputError
        On a malformed entry, unknown keys, or segments out of order or overlapping.
    """
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise UserInputError(f"scanning.segments={value!r} is not accepted; expected a list of segments "
                             "(kind, start_tcb, end_tcb, ref_epoch_tcb, nu_ref_deg, omega_ref_deg)")
    known = {f.name for f in fields(Segment)} - {"key"}
    out = []
    for i, item in enumerate(value):
        key = f"scanning.segments[{i}]"
        if isinstance(item, Segment):
            out.append(item)
            continue
        if not isinstance(item, Mapping):
            raise UserInputError(f"{key}={item!r} is not accepted; expected a mapping with keys {sorted(known)}")
        # dataclasses.asdict of a law carries the error-message prefix of its segments.
        item = {k: v for k, v in item.items() if k != "key"}
        unknown = sorted(set(item) - known)
        if unknown:
            raise UserInputError(f"{key} keys {unknown} are not accepted; expected some of {sorted(known)}")
        missing = sorted({"start_tcb", "end_tcb", "ref_epoch_tcb", "nu_ref_deg", "omega_ref_deg"} - set(item))
        if missing:
            raise UserInputError(f"{key} without {missing} is not accepted; expected every segment to give "
                                 "kind, start_tcb, end_tcb, ref_epoch_tcb, nu_ref_deg and omega_ref_deg")
        out.append(Segment(key=key, **dict(item)))
    segs = tuple(out)
    check_sequence(segs)
    return segs


def check_sequence(segs: tuple[Segment, ...]) -> None:
    """Bounded segments in time order, not overlapping (gaps between them are allowed)."""
    for i, seg in enumerate(segs):
        if seg.start_tcb is None or seg.end_tcb is None:
            raise UserInputError(f"scanning.segments[{i}] with start_tcb={seg.start_tcb!r}, end_tcb={seg.end_tcb!r} "
                                 "is not accepted; expected both dates (outside the list the law is extrapolated)")
        if i and seg.start_jd < segs[i - 1].end_jd:
            raise UserInputError(f"scanning.segments[{i}].start_tcb={seg.start_tcb!r} is not accepted; expected "
                                 f"a date at or after the end of segment {i - 1} ({segs[i - 1].end_tcb})")


# Gaia's scanning law as flown, from the research note scanning-law-history.md (its table,
# one row per segment): phases fitted per segment to GOST forecasts over random directions;
# "accuracy" = median |dt| of transit times, median |dpsi| of scan angles and the share of
# forecast transits without a model transit within 30 min.
FLOWN_SEGMENTS: tuple[Segment, ...] = (
    # Start of routine operations to the end of the EPSL: nu held at 180 deg, Omega continuous
    # with the next segment at 2014-08-23 (note: 0.00 min, 0.002 deg, 161 transits).
    Segment(kind="epsl", start_tcb="2014-07-25T10:30:00", end_tcb="2014-08-23T00:00:00",
            ref_epoch_tcb="2014-08-23T00:00:00", nu_ref_deg=180.0, omega_ref_deg=330.518),
    # NSL from the end of the EPSL to the re-phasing (note: 0.01 min, 0.004 deg).
    Segment(kind="nsl", start_tcb="2014-08-23T00:00:00", end_tcb="2014-09-25T11:30:00",
            ref_epoch_tcb="2014-08-23T00:00:00", nu_ref_deg=180.006, omega_ref_deg=330.518),
    # After the re-phasing: the single law of mcsweep's first versions, unchanged
    # (note: 0.01 min, 0.002 deg, 0.1 % unmatched). Holds the paper's Oct 2014 - 2015 window.
    Segment(kind="nsl", start_tcb="2014-09-25T11:30:00", end_tcb="2017-01-27T00:00:00",
            ref_epoch_tcb="2015-01-01T00:00:00", nu_ref_deg=323.3708, omega_ref_deg=95.1324),
    # 2017-01-27 - 2017-02-08: no transits in the forecasts (a gap, no segment).
    # nu continues the previous segment, the spin phase re-set 82.5 deg lower
    # (note: 0.01 min, 0.002 deg, 0.2 %).
    Segment(kind="nsl", start_tcb="2017-02-08T00:00:00", end_tcb="2019-07-05T00:00:00",
            ref_epoch_tcb="2017-02-08T12:00:00", nu_ref_deg=51.062, omega_ref_deg=169.969),
    # Reversed precession, phases refitted 2026-11-28 (note: 0.01 min, 0.001-0.002 deg, 0.2 %
    # unmatched over 2019-08 - 2020-07; 2.8-3.8 % over the whole segment). The earlier fit,
    # nu = 315.314 deg and Omega = 169.887 deg, left nu 0.57 deg off: scan circles tilted by
    # ~0.3 deg and about a third of the transits in the other field of view or the next spin.
    Segment(kind="nsl_reversed", start_tcb="2019-07-05T00:00:00", end_tcb="2020-08-01T00:00:00",
            ref_epoch_tcb="2019-07-05T00:00:00", nu_ref_deg=314.6231, omega_ref_deg=170.3941),
    # NSL to the end of science operations (note: 0.01 min, 0.002 deg, <= 0.2 %).
    Segment(kind="nsl", start_tcb="2020-08-01T00:00:00", end_tcb="2025-01-15T00:00:00",
            ref_epoch_tcb="2020-08-01T00:00:00", nu_ref_deg=244.289, omega_ref_deg=32.975),
)


#: Observation spans of the Gaia data releases, [start, end) in TCB (research note
#: scanning-law-history.md, from the Gaia Collaboration release papers; each starts at
#: the start of routine operations). The ``observations=dr1..dr5`` presets.
DATA_RELEASE_SPANS = {
    "dr1": ("2014-07-25T10:30:00", "2015-09-16T00:00:00"),
    "dr2": ("2014-07-25T10:30:00", "2016-05-23T00:00:00"),
    "dr3": ("2014-07-25T10:30:00", "2017-05-28T00:00:00"),  # also EDR3
    "dr4": ("2014-07-25T10:30:00", "2020-01-20T00:00:00"),
    "dr5": ("2014-07-25T10:30:00", "2025-01-15T00:00:00"),  # end of science operations
}
