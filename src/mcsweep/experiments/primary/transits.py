"""The stars' transits, per partition of the solution's table (paper Sect. 4.2, step 2).

A partition is a run of consecutive stars of the table (on one machine the whole table, on
a Dask cluster a piece of the sky, :mod:`~.sky`). Its tasks (``partition_*``) are the same
wherever it is: its FoV transits, each star's live transits (:func:`transit_summary`), what
the driver needs of it (its solved stars and their transits, its measurements per solver
block) and its rows of the per-star results. Each star's numbers are sums over its own
transits, so a partition's equal the whole table's, bit for bit.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...scanning.timeline import DeadTime
from ..global_solution.classes import star_transits
from .experiment import PrimarySettings, epoch_offset_yr, star_sigmas

__all__ = ["transits_of", "transit_summary", "with_transit_columns", "measurements_per_star", "first_rows",
           "block_transits", "partition_transits", "partition_summary", "partition_digest", "partition_block_counts",
           "partition_columns"]


def transits_of(job) -> tuple[int, dict]:
    """FoV transits of one chunk of stars (executor task): (chunk index, arrays)."""
    index, first, ra, dec, start_jd, end_jd, law = job
    # the field of view (1 byte per transit) for the basic-angle calibration (mcsweep.solver.calibration)
    return index, star_transits(ra, dec, start_jd, end_jd, law, first=first, with_fov=True)


def transit_summary(star, t, dead: DeadTime, first: int, n: int) -> dict:
    """Per star ``first .. first + n - 1`` from its transits (``star``, TCB JD ``t``, sorted by
    star): ``n_fov`` (live FoV transits), ``n_scheduled`` (FoV transits before the dead time),
    ``mean_tcb_jd`` (mean live epoch, TCB JD), ``span_days`` (days between the first and last
    live transit); and
    ``live`` per transit. Each star's numbers are sums
    over its own transits in their order, so a chunk's equal the whole set's, bit for bit."""
    live = ~dead.is_dead(t)
    local = np.asarray(star, dtype=np.int64) - first
    n_fov = np.bincount(local, weights=live, minlength=n).astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_tcb_jd = np.bincount(local, weights=np.where(live, t, 0.0), minlength=n) / n_fov
    t_live = np.where(live, t, np.nan)
    span_days = np.full(n, np.nan)
    if local.size:
        starts = np.flatnonzero(np.r_[True, local[1:] != local[:-1]])
        with np.errstate(invalid="ignore"):
            span_days[local[starts]] = (np.fmax.reduceat(t_live, starts) - np.fmin.reduceat(t_live, starts))
    n_scheduled = np.bincount(local, minlength=n).astype(np.int64)
    return {"n_fov": n_fov, "n_scheduled": n_scheduled, "mean_tcb_jd": mean_tcb_jd, "span_days": span_days,
            "live": live}


def with_transit_columns(settings: PrimarySettings, stars: pd.DataFrame, summary: dict) -> pd.DataFrame:
    """``stars`` with ``n_fov``, ``n_fov_scheduled`` (before the dead time), ``epoch_offset_yr`` (each star's mean live epoch relative to the
    reference epoch: evaluation_epoch='star_mean') and ``span_days`` (the time spans of the
    <= 4 transit subset)."""
    stars = stars.copy()
    stars["n_fov"] = summary["n_fov"]
    stars["n_fov_scheduled"] = summary["n_scheduled"]
    stars["epoch_offset_yr"] = epoch_offset_yr(settings, summary["mean_tcb_jd"])
    stars["span_days"] = summary["span_days"]
    return stars


def measurements_per_star(n_fov: np.ndarray, sigma_ac_mas) -> np.ndarray:
    """One AL measurement per live FoV transit, one AC where its sigma is finite."""
    return np.asarray(n_fov, dtype=np.int64) * (1 + (np.isfinite(sigma_ac_mas) if sigma_ac_mas is not None else 0))


def first_rows(per_block: np.ndarray) -> np.ndarray:
    """First measurement of each block from the blocks' numbers of measurements."""
    return np.concatenate([[0], np.cumsum(per_block)[:-1]]).astype(np.int64) if len(per_block) else \
        np.zeros(0, np.int64)


def block_transits(star, t, psi, live, solved_block: np.ndarray, following=None):
    """The live transits of one block's stars ``solved_block`` (sorted star indices) among
    transits sorted by star that include all of theirs: (star within the block, t, psi,
    ``following`` of those transits or None)."""
    lo, hi = np.searchsorted(star, [solved_block[0], solved_block[-1] + 1])
    idx = np.searchsorted(solved_block, star[lo:hi])
    # (AL only: a star of one transit lies in the range without being solved)
    ok = live[lo:hi] & (solved_block[np.minimum(idx, solved_block.size - 1)] == star[lo:hi])
    return idx[ok], t[lo:hi][ok], psi[lo:hi][ok], None if following is None else following[lo:hi][ok]


def partition_transits(part: pd.DataFrame, first: int, start_jd: float, end_jd: float, law) -> dict:
    """FoV transits of a partition of the table whose first star is ``first``, sorted by star."""
    return star_transits(part["ra"].to_numpy(), part["dec"].to_numpy(), start_jd, end_jd, law, first=first)


def partition_summary(transits: dict, dead, first: int, n: int, min_fov: int) -> dict:
    """Per star of a partition: live FoV transits, scheduled ones, mean live epoch, span, and
    whether it is solved (at least ``min_fov`` live FoV transits)."""
    out = transit_summary(transits["star"], transits["t"], dead, first, n)
    out.pop("live")
    out["solved"] = out["n_fov"] >= min_fov
    return out


def partition_digest(summary: dict) -> dict:
    """What the driver needs of a partition: its solved stars and their live FoV transits."""
    solvable = summary["solved"]
    return {"n_solved": int(np.count_nonzero(solvable)), "n_fov": int(summary["n_fov"][solvable].sum())}


def partition_block_counts(summary: dict, part: pd.DataFrame, offset: int, block_stars: int, settings) -> tuple:
    """The measurements of a partition's solved stars (the first is solved star ``offset``)
    summed by solver block: (first block, sums)."""
    n_fov, solvable = summary["n_fov"], summary["solved"]
    counts = measurements_per_star(n_fov[solvable], star_sigmas(settings, part, solvable)[1])
    if not counts.size:
        return 0, np.zeros(0, dtype=np.int64)
    k = (offset + np.arange(counts.size)) // block_stars
    return int(k[0]), np.bincount(k - k[0], weights=counts).astype(np.int64)


def partition_columns(part: pd.DataFrame, summary: dict, lo: int, hi: int) -> dict:
    """Rows ``lo:hi`` of a partition as the per-star results have them, and which are solved
    (with the number of solved stars before row ``lo``)."""
    solvable = summary["solved"]
    return {"class_key": part["class_key"].to_numpy()[lo:hi], "n_fov": summary["n_fov"][lo:hi],
            "n_fov_scheduled": summary["n_scheduled"][lo:hi], "span_days": summary["span_days"][lo:hi],
            "solved": solvable[lo:hi], "solved_before": int(np.count_nonzero(solvable[:lo]))}
