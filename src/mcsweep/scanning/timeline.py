"""Random losses of observations: dead time on the time line and dilution of FoV transits.

Both are drawn so that the result depends only on the seed of the generator and on
the inputs, never on how the stars are split into chunks or over processes:

* Dead time is drawn *once*, on the time line, before any star is looked at: the
  interval ``[start, end)`` is cut into outages of ``outage_days`` and exactly
  ``round(fraction * n_outages)`` of them, chosen uniformly without replacement, are
  dead. A transit inside a dead outage is lost.
* Dilution removes each FoV transit independently with probability ``p``. The
  uniform number of a transit is a counter-based hash (SplitMix64, Steele et al. 2014,
  OOPSLA) of one 64-bit key drawn from the generator, the source index, the FoV and
  the hour of the transit. The draw of a given transit is therefore the same in any
  chunk, process or order (and does not change when other stars are added).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..renamed_names import renamed_keyword

__all__ = ["DeadTime", "draw_dead_time", "dilution_key", "keep_after_dilution", "splitmix64"]

_U64 = np.uint64


@dataclass(frozen=True)
class DeadTime:
    """Dead intervals on the time line (TCB JD); ``starts`` sorted, intervals ``[start, stop)``."""

    starts: np.ndarray
    stops: np.ndarray

    def is_dead(self, tcb_jd) -> np.ndarray:
        """True where ``tcb_jd`` falls in a dead interval."""
        t = np.asarray(tcb_jd, dtype=float)
        if self.starts.size == 0:
            return np.zeros(t.shape, dtype=bool)
        i = np.searchsorted(self.starts, t, side="right") - 1
        ok = i >= 0
        dead = np.zeros(t.shape, dtype=bool)
        dead[ok] = t[ok] < self.stops[i[ok]]
        return dead

    @property
    def total_days(self) -> float:
        """Summed length of the dead intervals [day]."""
        return float(np.sum(self.stops - self.starts))


def draw_dead_time(start_jd: float, end_jd: float, fraction: float, *, outage_days: float | None = None,
                   rng: np.random.Generator, block_days: float | None = None) -> DeadTime:
    """Draw dead outages covering ``fraction`` of ``[start_jd, end_jd)``.

    Parameters
    ----------
    start_jd, end_jd : float
        Interval (TCB Julian dates) [day].
    fraction : float
        Dead fraction of the time line, in [0, 1).
    outage_days : float
        Length of one outage [day]; the last one is cut at ``end_jd``.
    rng : numpy.random.Generator
        Source of randomness (used only when ``fraction > 0``).
    block_days : float, optional
        Deprecated name of ``outage_days``.

    Returns
    -------
    DeadTime
    """
    outage_days = renamed_keyword("draw_dead_time", "block_days", block_days, "outage_days", outage_days)
    empty = np.empty(0)
    if fraction <= 0.0:
        return DeadTime(empty, empty)
    n_outages = max(1, math.ceil((end_jd - start_jd) / outage_days))
    n_dead = int(round(fraction * n_outages))
    idx = np.sort(rng.choice(n_outages, size=n_dead, replace=False))
    starts = start_jd + idx * outage_days
    stops = np.minimum(starts + outage_days, end_jd)
    return DeadTime(starts, stops)


def splitmix64(x: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser applied elementwise to ``uint64`` values (wrapping arithmetic)."""
    x = np.asarray(x, dtype=_U64)
    with np.errstate(over="ignore"):
        z = x + _U64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> _U64(30))) * _U64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> _U64(27))) * _U64(0x94D049BB133111EB)
        return z ^ (z >> _U64(31))


def dilution_key(rng: np.random.Generator) -> int:
    """Draw the 64-bit key of one dilution realisation from ``rng``."""
    return int(rng.integers(0, 2**64, dtype=np.uint64))


def keep_after_dilution(key: int, source_index, fov_is_f, tcb_jd, probability: float) -> np.ndarray:
    """Which FoV transits survive a dilution that removes each with ``probability``.

    Parameters
    ----------
    key : int
        From :func:`dilution_key`.
    source_index : array_like of int
        Index of the source of each transit.
    fov_is_f : array_like of bool
        True for the following FoV.
    tcb_jd : array_like of float
        Transit times; the hour ``round(24 * tcb_jd)`` identifies the transit (two
        transits of one source in one FoV are at least one spin, ~6 h, apart).
    probability : float
        Removal probability in [0, 1].

    Returns
    -------
    ndarray of bool
        True for the transits that are kept.
    """
    src = np.asarray(source_index).astype(_U64)
    hour = np.round(24.0 * np.asarray(tcb_jd, dtype=float)).astype(np.int64).astype(_U64)
    fov = np.asarray(fov_is_f, dtype=bool).astype(_U64)
    with np.errstate(over="ignore"):
        h = splitmix64(_U64(key) ^ splitmix64(src))
        h = splitmix64(h ^ (hour * _U64(2) + fov))
    uniform = (h >> _U64(11)).astype(float) * 2.0**-53
    return uniform >= probability
