"""A primary solution's per-star results: their columns, and their parts.

The results of one solution (one row per star of the solution's table, solved or not) are
made, written and read in parts of :data:`PART_STARS` stars (:func:`parts_of`), so neither
the run's driver nor its tables (:mod:`~.primary_cells`) hold a whole solution: on a
cluster each part is gathered from the workers that hold its stars when it is written
(:mod:`~.primary_cluster`).
"""

from __future__ import annotations

from typing import Callable, Iterator

import numpy as np
import pandas as pd


__all__ = ["PART_STARS", "parts_of", "StarParts", "results_frame", "solved_results"]

#: Stars per part of a solution's per-star results (one file each in the run's store): a
#: part's columns are some 7 MB, so reading one (or, for the factor's patterns, one of every
#: solution) keeps the reduction's memory flat.
PART_STARS = 250_000


def parts_of(n_stars: int) -> list[slice]:
    """The parts of a solution's ``n_stars`` per-star results (at least one, maybe empty)."""
    return [slice(lo, min(lo + PART_STARS, n_stars)) for lo in range(0, max(n_stars, 1), PART_STARS)]


class StarParts:
    """A solution's per-star results, one part of :data:`PART_STARS` stars at a time
    (:func:`parts_of`): columns ``star``, ``class_key``, ``n_fov``,
    ``n_fov_scheduled``, ``inside`` (1/0, -1 not solved), ``err_mas``, ``err_parallax_mas``,
    ``sigma_prior_mas``, ``span_days``. ``make(rows)`` gives the part of star ``rows``."""

    def __init__(self, n_stars: int, make: Callable[[slice], pd.DataFrame]):
        self.n_stars = int(n_stars)
        self._make = make

    def parts(self) -> Iterator[pd.DataFrame]:
        for rows in parts_of(self.n_stars):
            yield self._make(rows)

    def frame(self) -> pd.DataFrame:
        """Every part in one frame (small runs and tests: the whole solution in memory)."""
        return pd.concat(list(self.parts()), ignore_index=True)


def solved_results(first: int, class_key, n_fov, n_scheduled, span, solved, outcome) -> pd.DataFrame:
    """:func:`results_frame` of stars of which only ``solved`` (indices or a mask) have a
    solution: ``outcome = (inside, err, err_plx, sigma_prior)`` of those; the others are
    flagged -1 with NaN errors."""
    n = len(class_key)
    inside = np.full(n, -1, dtype=np.int8)
    err, err_plx, sigma_prior = (np.full(n, np.nan) for _ in range(3))
    for target, values in zip((inside, err, err_plx, sigma_prior), outcome):
        target[solved] = values
    return results_frame(first, class_key, n_fov, n_scheduled, span, inside, err, err_plx, sigma_prior)


def results_frame(first: int, class_key, n_fov, n_scheduled, span, inside, err, err_plx, sigma_prior) -> pd.DataFrame:
    """The per-star results of stars ``first, first + 1, ...`` (:class:`StarParts`' columns, the
    dtypes of the stored parts)."""
    n = len(inside)
    return pd.DataFrame({"star": np.arange(first, first + n, dtype=np.int32), "class_key": np.asarray(class_key),
                         "n_fov": np.asarray(n_fov).astype(np.int16),
                         "n_fov_scheduled": np.asarray(n_scheduled).astype(np.int16), "inside": inside,
                         "err_mas": np.asarray(err).astype(np.float32),
                         "err_parallax_mas": np.asarray(err_plx).astype(np.float32),
                         "sigma_prior_mas": np.asarray(sigma_prior).astype(np.float32),
                         "span_days": np.asarray(span).astype(np.float32)})
