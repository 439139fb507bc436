"""Random subsets of each source's real FoV transits, drawn and assembled without a loop over draws.

Units. A *transit* is one row of the epoch file (one FoV transit with its CCDs; two rows of
one source may share their CCD times, and both count, as AGIS counts both rows'
observations, :mod:`mcsweep.astrometry.source_update`). A *visit* is a run of a source's
consecutive transits less than :data:`~mcsweep.scanning.groups.VISIT_MAX_GAP_DAYS` (1 day)
and :data:`~mcsweep.scanning.groups.VISIT_MAX_TURN_DEG` (5 deg of scan angle) apart: the
distinct transits of the paper's Table 1 (:func:`mcsweep.scanning.groups.assign_groups`),
each transit taken at its first kept CCD's time and scan angle.

Draws. For source ``s``, unit ``u`` and size ``k`` the ``draws`` subsets are independent
uniform k-subsets of the source's items: each draw ranks the items by uniform random keys
and keeps the k smallest. The keys come from the source's own generator,
``SeedSequence(seed, spawn_key=(TAG, DRAW_STREAM, source_id, unit index, k))``, so a
source's subsets do not depend on which other sources the file holds, on their order, on
the chunks or on the workers. A source with fewer than k items has no subset of that size.

Assembly. The chosen items of every draw of every source of a chunk are one boolean array
(sources x draws x items); the CCD rows of the chosen items are found at once and become one
:class:`~mcsweep.astrometry.epoch_astrometry.CcdObservations` whose ``source_id`` is the draw's
number, ``source index x draws + draw``, so :func:`mcsweep.astrometry.source_update.source_normals`
forms every subset's normal equations in one call.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ...astrometry.epoch_astrometry import CcdObservations
from ...scanning.groups import assign_groups

__all__ = ["TAG", "DRAW_STREAM", "BOOTSTRAP_STREAM", "UNITS", "SourceLayout", "source_layout", "draw_seed",
           "choose_items", "subset_rows", "subset_observations"]

#: First element of every spawn key of this experiment (41: Sect. 4.1, 42: Sect. 4.2,
#: 43: the real-sky validation; 99 is the registry test's throwaway experiment).
TAG = 44
#: Second element: the subsets' draws and the bootstrap resamples of the sources.
DRAW_STREAM, BOOTSTRAP_STREAM = 1, 2
#: The units of a subset, by their index in the spawn keys.
UNITS = ("transits", "visits")


@dataclass(frozen=True)
class SourceLayout:
    """Where each source's CCD rows, transits and visits are in observations sorted by source.

    Per source (S): ``source_id``, ``row_start``, ``n_rows``, ``n_items`` (unit -> transits or
    visits). Per CCD row (R): ``item_of_row`` (unit -> 0-based transit or visit of the row
    within its source, numbered in time order).
    """

    source_id: np.ndarray
    row_start: np.ndarray
    n_rows: np.ndarray
    n_items: dict
    item_of_row: dict


def source_layout(obs: CcdObservations) -> SourceLayout:
    """The :class:`SourceLayout` of ``obs`` (sorted by source_id, as read)."""
    sid = obs.source_id
    starts = np.flatnonzero(np.r_[True, sid[1:] != sid[:-1]]) if sid.size else np.empty(0, np.int64)
    n_rows = np.diff(np.r_[starts, sid.size])
    src_of_row = np.repeat(np.arange(starts.size), n_rows)
    # One entry per transit: its first kept CCD in time (the CCDs of one transit span ~40 s).
    order = np.lexsort((obs.tcb_jd, obs.transit))
    first = order[np.r_[True, obs.transit[order][1:] != obs.transit[order][:-1]]] if sid.size else order
    by_time = first[np.lexsort((obs.tcb_jd[first], src_of_row[first]))]
    tr_src = src_of_row[by_time]
    tr_start = np.flatnonzero(np.r_[True, tr_src[1:] != tr_src[:-1]]) if tr_src.size else np.empty(0, np.int64)
    ordinal = np.arange(tr_src.size) - np.repeat(tr_start, np.diff(np.r_[tr_start, tr_src.size]))
    visit = assign_groups(tr_src, obs.tcb_jd[by_time], obs.scan_angle_deg[by_time])
    # Each row takes its transit's numbers (transit ids are the file's rows: unique in obs).
    tid_sorted = np.argsort(obs.transit[by_time], kind="stable")
    pos = tid_sorted[np.searchsorted(obs.transit[by_time][tid_sorted], obs.transit)]
    n_transits = np.bincount(tr_src, minlength=starts.size)
    n_visits = np.zeros(starts.size, np.int64)
    np.maximum.at(n_visits, tr_src, visit.astype(np.int64) + 1)
    return SourceLayout(source_id=sid[starts], row_start=starts, n_rows=n_rows,
                        n_items={"transits": n_transits, "visits": n_visits},
                        item_of_row={"transits": ordinal[pos], "visits": visit[pos].astype(np.int64)})


def draw_seed(seed: int, source_id: int, unit: str, k: int) -> np.random.SeedSequence:
    """The seed of one source's subsets of ``k`` ``unit`` (module notes)."""
    return np.random.SeedSequence(int(seed), spawn_key=(TAG, DRAW_STREAM, int(source_id), UNITS.index(unit), int(k)))


def choose_items(seed: int, source_id: np.ndarray, n_items: np.ndarray, unit: str, k: int,
                 n_draws: int) -> np.ndarray:
    """Chosen items of every draw: bool (S, draws, M + 1), M = the most items of a source.

    The last column is never chosen (padding rows point there). A source with fewer than
    ``k`` items has no chosen item.
    """
    n_items = np.asarray(n_items, dtype=np.int64)
    S = n_items.size
    M = int(max(n_items.max(initial=0), k))
    keys = np.full((S, n_draws, M), np.inf)
    # One generator per source (its own stream, module notes): the only loop over sources,
    # one call each; ranking and assembly below are vectorised.
    for s in np.flatnonzero(n_items >= k):
        keys[s, :, :n_items[s]] = np.random.default_rng(draw_seed(seed, source_id[s], unit, k)).random(
            (n_draws, int(n_items[s])))
    chosen = np.argsort(keys, axis=2, kind="stable")[:, :, :k]
    sel = np.zeros((S, n_draws, M + 1), dtype=bool)
    np.put_along_axis(sel, chosen, True, axis=2)
    sel[n_items < k] = False
    return sel


def subset_rows(row_start: np.ndarray, n_rows: np.ndarray, item_of_row: np.ndarray,
                sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(CCD row, draw number) of every row of every chosen subset, sorted by draw then row.

    ``sel`` from :func:`choose_items`; the draw number is ``source index x draws + draw``.
    """
    S, D, M1 = sel.shape
    if S == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    r_max = int(n_rows.max())
    pos = np.arange(r_max)
    real = pos[None, :] < n_rows[:, None]
    rows = np.where(real, row_start[:, None] + pos, 0)
    items = np.where(real, item_of_row[rows], M1 - 1)
    # (S, r_max, D) by advanced indexing on axes 0 and 2; viewed as (S, D, r_max) so that
    # nonzero lists the rows grouped by draw.
    picked = sel[np.arange(S)[:, None], :, items].transpose(0, 2, 1)
    s, d, r = np.nonzero(picked)
    return row_start[s] + r, s * D + d


def subset_observations(obs: CcdObservations, rows: np.ndarray, draw: np.ndarray) -> CcdObservations:
    """The observations ``rows`` with ``source_id`` = the draw's number (module notes)."""
    return dataclasses.replace(obs.take(rows), source_id=draw.astype(np.int64))
