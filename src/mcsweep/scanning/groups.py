"""Distinct transits (the ``#`` column of the paper's Table 1) and their selection.

A star crosses the preceding FoV and, Gamma / omega_z later (1.77 h for Gaia), the
following FoV of the same spin revolution, along practically the same direction. As
the spin axis precesses slowly, the star may stay inside the across-scan acceptance
for the next spin (6 h later) or two, crossed along almost the same direction again.
Table 1 numbers "transit groups that are distinct in time and/or direction", and the
paper's two-transit case needs two different scan directions (Sect. 3.3): a group is
therefore one *visit* of the scanning circle to the star, all the transits of its
consecutive spins. A group may hold a single FoV transit when the other fell outside
the across-scan acceptance (Table 1, group 5), or was lost to dead time or dilution.

Rule used here, per source and in time order: a transit joins the group of the
source's previous transit when it follows it by at most :data:`VISIT_MAX_GAP_DAYS`
*and* its scan angle differs from that transit's by at most
:data:`VISIT_MAX_TURN_DEG`; otherwise it opens a new group. Justification:

* Table 1: the P/F pair of one spin (1.8 h apart, angles equal to 1 deg) is one group;
  the closest distinct groups are 21 days apart (#1 and #2), and #4 and #5 are 24 days
  and 83 deg apart.
* Flown law over the sweep's 48 directions, 2014-10-01 to 2016-01-01 (1069 transits):
  consecutive transits of one visit are at most 6.0 h apart (P -> F 1.8 h, F -> P of the
  next spin 4.2 h, same FoV one spin later 6.0 h) and turn by at most 1.07 deg; the
  shortest gaps between visits are 2.0 and 2.75 days (8 and 11 deg turns), all others
  5.25 days or more. 1 day allows for up to three spins lost to dead time or dilution
  inside a visit and stays a factor 2 below the shortest gap between visits.
* The spin axis precesses at about 4 deg/day (de Bruijne et al. 2010, S = 4.22; the
  turns between the closest visits above are 4.0-4.2 deg/day), so
  within 1 day the scan direction at a star turns by less than 5 deg; a larger turn
  means a different direction, i.e. a distinct transit even if close in time. (Time
  separates the visits of the flown law on its own: turns between visits start at
  1.05 deg.)

Consecutive spins are chained: where the scanning circle turns over a star it can stay
for up to 11 spins (60 h, 10.7 deg of total turn, 2 of the 48 directions' 491 visits
above), and those spins, none distinct from the next, are one visit.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ..errors import UserInputError

__all__ = ["VISIT_MAX_GAP_DAYS", "VISIT_MAX_TURN_DEG", "assign_groups", "select_groups", "group_summary"]

#: Largest time between consecutive transits of one visit [day] (module docstring).
VISIT_MAX_GAP_DAYS = 1.0
#: Largest change of scan angle between consecutive transits of one visit [deg].
VISIT_MAX_TURN_DEG = 5.0


def assign_groups(source_index, tcb_jd, scan_angle_deg, *, max_gap_days: float = VISIT_MAX_GAP_DAYS,
                  max_turn_deg: float = VISIT_MAX_TURN_DEG) -> np.ndarray:
    """0-based distinct-transit (visit) number of every transit, counted per source.

    Parameters
    ----------
    source_index : array_like of int
        Source of each transit; the rows must be sorted by (source, time).
    tcb_jd : array_like of float
        Transit times [day].
    scan_angle_deg : array_like of float
        Scan position angle psi of each transit [deg].
    max_gap_days : float
        A transit later than this after the source's previous one opens a new group [day].
    max_turn_deg : float
        A transit whose scan angle differs by more than this from the previous one's
        opens a new group [deg].

    Returns
    -------
    ndarray of int32
    """
    src = np.asarray(source_index)
    t = np.asarray(tcb_jd, dtype=float)
    psi = np.asarray(scan_angle_deg, dtype=float)
    n = src.size
    if n == 0:
        return np.empty(0, dtype=np.int32)
    new_source = np.ones(n, dtype=bool)
    new_source[1:] = src[1:] != src[:-1]
    turn = np.abs(np.mod(np.diff(psi) + 180.0, 360.0) - 180.0)
    joins = np.zeros(n, dtype=bool)
    joins[1:] = ~new_source[1:] & (np.diff(t) <= max_gap_days) & (turn <= max_turn_deg)
    opens = ~joins
    count = np.cumsum(opens)  # groups opened so far, over all sources
    first_of_source = np.flatnonzero(new_source)
    offset = np.repeat(count[first_of_source] - 1, np.diff(np.append(first_of_source, n)))
    return (count - 1 - offset).astype(np.int32)


def _group_counts(transits: pd.DataFrame) -> np.ndarray:
    """Number of groups of each row's source (rows sorted by source)."""
    src = transits["source_index"].to_numpy()
    grp = transits["group"].to_numpy()
    if src.size == 0:
        return np.empty(0, dtype=np.int64)
    last = np.ones(src.size, dtype=bool)
    last[:-1] = src[1:] != src[:-1]
    starts = np.flatnonzero(np.r_[True, src[1:] != src[:-1]])
    n_groups = grp[last].astype(np.int64) + 1
    return np.repeat(n_groups, np.diff(np.append(starts, src.size)))


def select_groups(transits: pd.DataFrame, which, *, complete: bool = False) -> pd.DataFrame:
    """Rows of the requested distinct transits of every source.

    Parameters
    ----------
    transits : pandas.DataFrame
        Output of :func:`mcsweep.scanning.find_transits` (sorted by source and time,
        with ``source_index`` and ``group``).
    which : int, str or sequence of int
        * an int ``k`` or the string ``"first k"``: the first ``k`` groups;
        * ``"all"``: every group;
        * a sequence of group numbers, 0-based; negative numbers count from each
          source's last group (``[0, -1]`` = first and last, the paper's "two
          diluted transits").
    complete : bool, keyword-only
        If True, keep only sources that have every requested group (for ``k``: at
        least ``k`` groups); otherwise keep whatever exists.

    Returns
    -------
    pandas.DataFrame
        The selected rows, same columns, original order; the ``group`` column keeps its
        original numbers.
    """
    indices = _parse_which(which)
    if transits.empty:
        return transits.copy()
    n_groups = _group_counts(transits)
    grp = transits["group"].to_numpy().astype(np.int64)
    if indices is None:  # "all"
        return transits.copy()
    keep = np.zeros(grp.size, dtype=bool)
    has_all = np.ones(grp.size, dtype=bool)
    for j in indices:
        resolved = j if j >= 0 else n_groups + j
        exists = (resolved >= 0) & (resolved < n_groups)
        keep |= exists & (grp == resolved)
        has_all &= exists
    if complete:
        keep &= has_all
    return transits.loc[keep].copy()


def _parse_which(which):
    if isinstance(which, str):
        text = which.strip().lower()
        if text == "all":
            return None
        parts = text.split()
        if len(parts) == 2 and parts[0] == "first" and parts[1].isdigit():
            return list(range(int(parts[1])))
        raise UserInputError(f"group selection {which!r} is not accepted; expected 'all', 'first k', "
                             "an int k or a list of group numbers")
    if isinstance(which, (int, np.integer)) and not isinstance(which, bool):
        if which < 0:
            raise UserInputError(f"group selection {which!r} is not accepted; expected k >= 0")
        return list(range(int(which)))
    if isinstance(which, Sequence) or isinstance(which, np.ndarray):
        out = []
        for j in which:
            if isinstance(j, bool) or not isinstance(j, (int, np.integer)):
                raise UserInputError(f"group selection {list(which)!r} is not accepted; "
                                     "expected a list of integer group numbers")
            out.append(int(j))
        # Repeated or overlapping (e.g. [0, -1] for a single-group star) requests select a row once.
        return out
    raise UserInputError(f"group selection {which!r} is not accepted; expected 'all', 'first k', "
                         "an int k or a list of group numbers")


def group_summary(transits: pd.DataFrame) -> pd.DataFrame:
    """One row per (source, group): first time, FoVs in time order and first scan angle.

    Returns
    -------
    pandas.DataFrame
        Columns ``source_index, group, tcb_jd`` (time of the group's first transit),
        ``fovs`` (the group's FoVs in time order, e.g. 'F', 'PF' or 'PFPF' for two
        spins), ``scan_angle_deg`` (of the first transit).
    """
    g = transits.groupby(["source_index", "group"], sort=True, observed=True)
    out = g.agg(tcb_jd=("tcb_jd", "first"), scan_angle_deg=("scan_angle_deg", "first"),
                fovs=("fov", lambda s: "".join(s.astype(str))))
    return out.reset_index()
