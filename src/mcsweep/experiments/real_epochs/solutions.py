"""Each source's truth from all its transits, and every subset's solutions against it.

Truth. A source's five parameters from all its kept AL CCD observations, without prior, at
the reference epoch of Gaia DR4, J2017.5 TCB (:func:`mcsweep.astrometry.source_update.source_normals`,
:func:`mcsweep.astrometry.solve.solve_no_prior`). A source whose normal matrix is singular or
ill-conditioned (``DEFAULT_MAX_CONDITION``) has no truth and no subsets.

Subsets. Each subset (:mod:`.subsets`) is solved at its own mean epoch of observation, the
paper's reference epoch (Sect. 2.1), with every prior of Eq. 18 (zero-centred,
sigma_mu = R sigma_plx; Eqs. 11-13) and position only (Table 2's "none (2 parameters)").
The truth's position at that epoch is the truth's at J2017.5 plus its proper motion times
the epoch difference: the design equations are linear in time in the local plane of the
source's reference position (:mod:`mcsweep.astrometry.source_update`), which both solutions
share, so nothing else changes between the epochs (the perspective term is negligible over
five years, the paper's footnote in Sect. 2.1). The position error is subset minus truth
in (alpha*, delta) [mas]; inside the P ellipse by :func:`mcsweep.astrometry.confidence.inside`,
with the project's NaN rule: a subset without a finite positive-definite position
covariance (e.g. two transits scanning in one direction) has no ellipse (flag -1) and is
left out of the fraction's denominator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...astrometry.confidence import inside as inside_ellipse
from ...astrometry.confidence import mahalanobis_sq
from ...astrometry.epoch_astrometry import CcdObservations
from ...astrometry.design import JULIAN_YEAR_DAYS
from ...astrometry.solve import solve_no_prior, solve_position_only, solve_with_prior
from ...astrometry.source_update import DR4_REFERENCE_EPOCH_JD, source_normals
from .subsets import UNITS, choose_items, source_layout, subset_observations, subset_rows

__all__ = ["TRUTH_EPOCH_JD", "POSITION_ONLY", "Truth", "solve_truth", "ChunkSettings",
           "SubsetSolutions", "solve_subsets", "solve_chunk"]

#: The truth's reference epoch: J2017.5 TCB, Gaia DR4's (source_update.DR4_REFERENCE_EPOCH_JD).
TRUTH_EPOCH_JD = DR4_REFERENCE_EPOCH_JD
#: The prior name of the position-only solution (Table 2's "none (2 parameters)").
POSITION_ONLY = "none"


@dataclass(frozen=True)
class Truth:
    """Per source (sorted by id): the all-transit five-parameter solution at J2017.5."""

    source_id: np.ndarray
    #: (n, 5): (alpha*, delta) offsets [mas] in the local plane, parallax [mas], proper motion [mas/yr].
    x: np.ndarray
    #: (n, 5) formal standard errors, same units.
    error: np.ndarray
    ok: np.ndarray
    n_transits: np.ndarray
    n_visibility_periods: np.ndarray
    time_span_yr: np.ndarray


def solve_truth(obs: CcdObservations) -> Truth:
    """Every source's truth (module notes)."""
    sn = source_normals(obs, model="5p", reference_epoch_jd=TRUTH_EPOCH_JD)
    sol = solve_no_prior(sn.N, sn.b)
    err = np.sqrt(np.diagonal(sol.cov, axis1=1, axis2=2))
    return Truth(source_id=sn.source_id, x=sol.x, error=err, ok=sol.ok, n_transits=sn.n_transits,
                 n_visibility_periods=sn.n_visibility_periods, time_span_yr=sn.time_span_yr)


@dataclass(frozen=True)
class ChunkSettings:
    """What a chunk of sources needs besides its data (picklable)."""

    seed: int
    draws: int
    #: unit -> subset sizes, e.g. {'transits': (2, 3, 4, 6), 'visits': (2, 3, 4, 6)}.
    sizes: dict
    #: Prior names in table order (without the position-only solution, which is always added).
    priors: tuple
    confidence: float
    ratio_R: float


@dataclass(frozen=True)
class SubsetSolutions:
    """Per subset (draw) of one unit and size: its source, the epoch and every prior's result."""

    source_index: np.ndarray
    draw: np.ndarray
    n_transits: np.ndarray
    epoch_jd: np.ndarray
    #: prior -> (n, 2) position error [mas], subset minus truth, (alpha*, delta).
    dpos: dict
    #: prior -> (n, 2, 2) position covariance [mas^2] (NaN where not solved).
    cov: dict
    #: prior -> int8 (n,): 1 inside the P ellipse, 0 outside, -1 no ellipse.
    flags: dict


def solve_subsets(obs: CcdObservations, truth_x: np.ndarray, sigma_mas: dict, rows: np.ndarray,
                  draw_number: np.ndarray, n_draws: int, *, ratio_R: float, confidence: float) -> SubsetSolutions:
    """Solve the subsets given by (CCD row, draw number) (module notes).

    ``truth_x`` (S, 5) and ``sigma_mas`` (prior -> (S,) parallax prior sigma [mas]) are per
    source of ``obs`` (its sources in id order); the draw number is ``source index x n_draws
    + draw`` (:func:`.subsets.subset_rows`).
    """
    sn = source_normals(subset_observations(obs, rows, draw_number), model="5p", reference_epoch_jd=None)
    s = sn.source_id // n_draws
    dt_yr = (sn.reference_epoch_jd - TRUTH_EPOCH_JD) / JULIAN_YEAR_DAYS
    truth_pos = truth_x[s, :2] + truth_x[s, 3:5] * dt_yr[:, None]
    dpos, cov, flags = {}, {}, {}
    for prior, sigma in {**sigma_mas, POSITION_ONLY: None}.items():
        sol = (solve_position_only(sn.N, sn.b) if sigma is None
               else solve_with_prior(sn.N, sn.b, np.asarray(sigma)[s], ratio_R))
        d = sol.position - truth_pos
        c = sol.position_cov
        valid = sol.ok & np.isfinite(mahalanobis_sq(d, c))
        flags[prior] = np.where(valid, inside_ellipse(d, c, confidence), -1).astype(np.int8)
        dpos[prior], cov[prior] = d, c
    return SubsetSolutions(source_index=s, draw=sn.source_id % n_draws, n_transits=sn.n_transits,
                           epoch_jd=sn.reference_epoch_jd, dpos=dpos, cov=cov, flags=flags)


def solve_chunk(settings: ChunkSettings, obs: CcdObservations, truth_x: np.ndarray, sigma_mas: dict) -> pd.DataFrame:
    """One row per subset of the chunk's sources: ``source_id``, ``unit``, ``k``, ``draw``,
    ``n_transits`` (FoV transits in the subset), ``epoch_offset_yr`` (its mean epoch minus
    J2017.5) and per prior ``inside_<prior>`` (1/0/-1) and ``err_<prior>_mas`` (|position
    error|, NaN without an ellipse).

    ``obs``: the chunk's sources' observations (sorted by source); ``truth_x`` (S, 5) and
    ``sigma_mas`` (prior -> (S,)) per source in id order.
    """
    layout = source_layout(obs)
    parts = []
    for unit in UNITS:
        for k in settings.sizes.get(unit, ()):
            sel = choose_items(settings.seed, layout.source_id, layout.n_items[unit], unit, k, settings.draws)
            rows, number = subset_rows(layout.row_start, layout.n_rows, layout.item_of_row[unit], sel)
            del sel
            if rows.size == 0:
                continue
            res = solve_subsets(obs, truth_x, sigma_mas, rows, number, settings.draws, ratio_R=settings.ratio_R,
                                confidence=settings.confidence)
            out = {"source_id": layout.source_id[res.source_index], "unit": unit,
                   "k": np.full(res.draw.size, k, np.int16), "draw": res.draw.astype(np.int32),
                   "n_transits": res.n_transits.astype(np.int16),
                   "epoch_offset_yr": ((res.epoch_jd - TRUTH_EPOCH_JD) / JULIAN_YEAR_DAYS).astype(np.float32)}
            for prior in (*settings.priors, POSITION_ONLY):
                f = res.flags[prior]
                out[f"inside_{prior}"] = f
                err = np.hypot(res.dpos[prior][:, 0], res.dpos[prior][:, 1])
                out[f"err_{prior}_mas"] = np.where(f >= 0, err, np.nan).astype(np.float32)
            parts.append(pd.DataFrame(out))
    if not parts:  # no source has enough transits or visits for any size: the columns, no row
        empty = {"source_id": np.empty(0, np.int64), "unit": np.empty(0, object), "k": np.empty(0, np.int16),
                 "draw": np.empty(0, np.int32), "n_transits": np.empty(0, np.int16),
                 "epoch_offset_yr": np.empty(0, np.float32)}
        for prior in (*settings.priors, POSITION_ONLY):
            empty[f"inside_{prior}"], empty[f"err_{prior}_mas"] = np.empty(0, np.int8), np.empty(0, np.float32)
        return pd.DataFrame(empty)
    return pd.concat(parts, ignore_index=True)
