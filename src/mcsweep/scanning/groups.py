"""Distinct transits (the ``#`` column of the paper's Table 1) and their selection.

A star crosses the preceding FoV and, Gamma / omega_z later (1.77 h for Gaia), the
following FoV of the same spin revolution, along practically the same direction.
Table 1 numbers such pairs as one "transit group that is distinct in time and/or
direction"; a group may hold only one FoV transit when the other fell outside the
across-scan acceptance (Table 1, group 5), or was lost to dead time or dilution.

Rule used here, per source and in time order: a transit opens a new group unless it
is an F transit that follows a P transit of the same source by the FoV lag
``Gamma / omega_z`` to within :data:`GROUP_LAG_TOLERANCE_DAYS`. Transits of
successive spins (6 h apart) are therefore separate groups.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ..errors import UserInputError

__all__ = ["GROUP_LAG_TOLERANCE_DAYS", "assign_groups", "select_groups", "group_summary"]

#: Allowed deviation of the P -> F time lag from Gamma / omega_z [day] (0.25 h; the
#: real deviation, from the slow motion of the spin axis, is below a second).
GROUP_LAG_TOLERANCE_DAYS = 0.25 / 24.0


def assign_groups(source_index, tcb_jd, fov_is_f, *, lag_days: float,
                  tolerance_days: float = GROUP_LAG_TOLERANCE_DAYS) -> np.ndarray:
    """0-based distinct-transit number of every transit, counted per source.

    Parameters
    ----------
    source_index : array_like of int
        Source of each transit; the rows must be sorted by (source, time).
    tcb_jd : array_like of float
        Transit times [day].
    fov_is_f : array_like of bool
        True for following-FoV transits.
    lag_days : float
        Nominal P -> F lag Gamma / omega_z [day].
    tolerance_days : float
        Allowed deviation from ``lag_days`` [day].

    Returns
    -------
    ndarray of int32
    """
    src = np.asarray(source_index)
    t = np.asarray(tcb_jd, dtype=float)
    is_f = np.asarray(fov_is_f, dtype=bool)
    n = src.size
    if n == 0:
        return np.empty(0, dtype=np.int32)
    new_source = np.ones(n, dtype=bool)
    new_source[1:] = src[1:] != src[:-1]
    joins = np.zeros(n, dtype=bool)
    joins[1:] = (~new_source[1:] & is_f[1:] & ~is_f[:-1]
                 & (np.abs(np.diff(t) - lag_days) <= tolerance_days))
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
    """One row per (source, group): first time, FoVs present and mean scan angle.

    Returns
    -------
    pandas.DataFrame
        Columns ``source_index, group, tcb_jd`` (time of the group's first transit),
        ``fovs`` ('P', 'F' or 'PF'), ``scan_angle_deg`` (of the first transit).
    """
    g = transits.groupby(["source_index", "group"], sort=True, observed=True)
    out = g.agg(tcb_jd=("tcb_jd", "first"), scan_angle_deg=("scan_angle_deg", "first"),
                fovs=("fov", lambda s: "".join(s.astype(str))))
    return out.reset_index()
