"""Table 3's table cells (prior x subset x class), the factor search's curves and the notes'
counts, reduced from per-star results read part by part.

A primary solution's per-star results are written in parts of :data:`PART_STARS` stars
(:func:`parts_of`); the run reduces them to its tables in two passes over the parts, so no
process holds a whole solution's stars:

1. per cell (prior x subset x class): the stars, those with a confidence region and those
   inside (Table 3's fractions, the factor curves); per cell (subset x class) the distinct
   patterns of inside flags over the factor grid with their counts (the factor's bootstrap,
   :func:`~mcsweep.experiments.f90_curve.pattern_interval`: a multinomial draw over the
   patterns is the bootstrap over the stars); and a histogram of each cell's errors on the
   top 16 bits of their float32 values (:class:`RankSelector`);
2. the values in the bins that hold the order statistics the percentiles and their rank
   intervals need: exact, the numbers :func:`numpy.percentile` and
   :func:`~mcsweep.astrometry.confidence.percentile_interval` give on all the values
   (tests).

The same reduction serves one part held in memory (:func:`~.table.table3_rows`,
:func:`~.factor.factor_rows`), so a table does not depend on how the stars were
split, and a run on a cluster gives the bits of a local one.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from ...astrometry.confidence import check_probability
from ..global_solution.classes import class_key
from ..global_solution.table import FRACTION_INTERVAL, SUBSETS, error_percentile, fraction_from_counts, subset_masks
from ...solver.selection import float_keys, quantile_from_neighbours, quantile_ranks
from ..f90_curve import flag_patterns, merge_patterns, pattern_interval, sigma_f90_from_curve

__all__ = ["RankSelector", "TableReduction", "reduce_parts", "rank_interval_indices"]

#: Quantiles of the spans of the <= 4 transit stars' live transits in the table notes.
SPAN_QUANTILES = (0.1, 0.5, 0.9)


def _quantile(sel: "RankSelector", quantile: float) -> float:
    """numpy's 'linear' quantile of the values ``sel`` ranked, from its two order statistics."""
    prev, nxt, gamma = quantile_ranks(sel.n, [quantile])
    return float(quantile_from_neighbours(sel.value(int(prev[0])), sel.value(int(nxt[0])), gamma)[0])


def _quantile_wanted(n: int, quantile: float) -> list[int]:
    """The ranks :func:`_quantile` needs."""
    prev, nxt, _ = quantile_ranks(n, [quantile])
    return [int(prev[0]), int(nxt[0])]


def rank_interval_indices(n: int, q: float, level: float) -> tuple[int, int]:
    """Ranks (0-based) of the order statistics bounding the distribution-free interval of the
    ``q``-th percentile of ``n`` values (Conover 1999, Sect. 3.2; the ranks of
    :func:`scipy.stats.quantile_test`'s two-sided interval, which
    :func:`~mcsweep.astrometry.confidence.percentile_interval` uses): -1 or ``n`` where the
    bound lies beyond the sample."""
    alpha = (1.0 - check_probability(level)) / 2.0
    dist = stats.binom(n, float(q) / 100.0)
    return int(dist.ppf(alpha)) - 1, int(dist.isf(alpha))


class RankSelector:
    """Exact order statistics of a stream of float32 values, in two passes over the stream.

    Pass 1 (:meth:`count`) histograms the values on the top :data:`KEY_BITS` bits of an
    order-preserving integer key of their float32 bits; :meth:`want` names the ranks wanted;
    pass 2 (:meth:`collect`) keeps only the values in the bins that hold them; :meth:`value`
    sorts those. Memory: the histogram (0.5 MB) and the values of a few bins. Non-finite
    values are counted apart and never ranked (the finite values' order statistics).
    """

    KEY_BITS = 16

    def __init__(self):
        self.hist = np.zeros(1 << self.KEY_BITS, dtype=np.int64)
        self.n_nonfinite = 0
        self._start: dict[int, int] = {}   # wanted rank -> rank of its bin's first value
        self._wanted: dict[int, int] = {}  # wanted rank -> its bin
        self._bins: dict[int, list] = {}   # bin -> the values kept in pass 2
        self._sorted: set[int] = set()     # bins already joined and sorted

    @staticmethod
    def _finite(values) -> tuple[np.ndarray, np.ndarray]:
        v = np.asarray(values, dtype=np.float32).ravel()
        v = v[np.isfinite(v)]
        return v, float_keys(v, np.float32) >> np.uint32(32 - RankSelector.KEY_BITS)

    def count(self, values) -> None:
        """Pass 1: histogram ``values``."""
        n = np.size(values)
        v, bins = self._finite(values)
        self.n_nonfinite += n - v.size
        self.hist += np.bincount(bins, minlength=self.hist.size)

    @property
    def n(self) -> int:
        """Finite values counted."""
        return int(self.hist.sum())

    def want(self, ranks) -> None:
        """After pass 1: the ranks (0-based among the finite values) :meth:`value` will give."""
        cum = np.cumsum(self.hist)
        for r in map(int, ranks):
            if 0 <= r < cum[-1]:
                b = int(np.searchsorted(cum, r, side="right"))
                self._start[r], self._wanted[r] = int(cum[b] - self.hist[b]), b
                self._bins.setdefault(b, [])

    def collect(self, values) -> None:
        """Pass 2: keep the values of ``values`` in the bins of the wanted ranks."""
        if not self._bins:
            return
        v, bins = self._finite(values)
        for b, kept in self._bins.items():
            kept.append(v[bins == b])

    def value(self, rank: int) -> float:
        """The finite values' order statistic of ``rank`` (wanted before pass 2), as float64."""
        b = self._wanted[rank]
        kept = self._bins[b]
        if b not in self._sorted:
            kept[:] = [np.sort(np.concatenate(kept))]
            self._sorted.add(b)
        return float(kept[0][rank - self._start[rank]])


@dataclasses.dataclass
class _Cell:
    """One cell's counts and its errors' order statistics."""

    n_stars: int = 0
    n_valid: int = 0
    n_inside: int = 0
    errors: RankSelector = dataclasses.field(default_factory=RankSelector)
    #: the ranks of the percentile's interval (:func:`rank_interval_indices`), set by the plan
    interval_ranks: tuple[int, int] = (-1, -1)


def _errors(part: pd.DataFrame) -> np.ndarray | None:
    """A part's position errors [mas] (None: a part without them, as the factor curves' inputs may be)."""
    return part["err_mas"].to_numpy() if "err_mas" in part else None


class TableReduction:
    """The reduction of one run's solutions (module notes).

    ``labels``: every solution read (Table 3's priors and the factor grid's); ``factors``:
    factor k -> its solution's label (empty: no factor search); ``count``: the per-star
    column that counts transits for the subsets
    (:data:`~mcsweep.experiments.primary.table.SUBSET_COUNTS`); ``ranked``: the labels whose
    errors are ranked for their percentiles (default every label; a solution only in the
    factor grid needs its counts alone).
    """

    def __init__(self, labels: Sequence[str], g_classes: Sequence[float], confidence: float, *,
                 count: str = "n_fov", factors: Mapping[float, str] | None = None,
                 ranked: Sequence[str] | None = None):
        self.labels = list(dict.fromkeys(labels))
        self.ranked = set(self.labels if ranked is None else ranked)
        self.g_classes = [float(g) for g in g_classes]
        self.confidence = float(confidence)
        self.count = count
        self.factors = dict(sorted((float(k), v) for k, v in (factors or {}).items()))
        self.cells = {(lab, s, g): _Cell() for lab in self.labels for s in SUBSETS for g in self.g_classes}
        self.patterns: dict = {(s, g): {} for s in SUBSETS for g in self.g_classes}
        self.spans = {g: RankSelector() for g in self.g_classes}
        self.within_a_day = {g: 0 for g in self.g_classes}
        self.class_counts: dict[int, int] = {}
        self._planned = False

    def _masks(self, part: pd.DataFrame) -> dict:
        sub = subset_masks(part[self.count].to_numpy())
        key = part["class_key"].to_numpy()
        return {(s, g): sub[s] & (key == class_key(g)) for s in SUBSETS for g in self.g_classes}

    def _one(self, parts: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
        first = parts[self.labels[0]]
        if any(len(parts[lab]) != len(first) for lab in self.labels):
            raise ValueError("the parts of the solutions hold different stars")
        return first

    def count_part(self, parts: Mapping[str, pd.DataFrame]) -> None:
        """Pass 1 over one part of every solution (``parts[label]``: the same stars)."""
        if self._planned:
            raise RuntimeError("pass 1 is over")
        first = self._one(parts)
        masks = self._masks(first)
        keys, counts = np.unique(first["class_key"].to_numpy(), return_counts=True)
        for k, c in zip(keys.tolist(), counts.tolist()):
            self.class_counts[k] = self.class_counts.get(k, 0) + c
        n_fov = first["n_fov"].to_numpy()
        span = first["span_days"].to_numpy() if "span_days" in first else None
        for lab in self.labels:
            inside, err = parts[lab]["inside"].to_numpy(), _errors(parts[lab])
            for (s, g), m in masks.items():
                cell, flags = self.cells[lab, s, g], inside[m]
                valid = flags >= 0
                cell.n_stars += int(np.count_nonzero(m))
                cell.n_valid += int(np.count_nonzero(valid))
                cell.n_inside += int(np.count_nonzero(flags == 1))
                if err is not None and lab in self.ranked:
                    cell.errors.count(err[m][valid])
        for (s, g), m in masks.items():
            if self.factors:
                flags = np.stack([parts[lab]["inside"].to_numpy()[m] for lab in self.factors.values()])
                merge_patterns(self.patterns[s, g], flag_patterns(flags == 1, flags >= 0))
            if s == "<=4" and span is not None:
                sp = span[m & (n_fov >= 1)]
                self.within_a_day[g] += int(np.count_nonzero(sp < 1))
                self.spans[g].count(sp)

    def plan(self) -> None:
        """Between the passes: name the order statistics pass 2 keeps."""
        q = error_percentile(self.confidence)
        for cell in self.cells.values():
            n = cell.errors.n
            if n:
                cell.interval_ranks = rank_interval_indices(n, q, FRACTION_INTERVAL)
                cell.errors.want([*_quantile_wanted(n, np.true_divide(q, 100)), *cell.interval_ranks])
        for sel in self.spans.values():
            if sel.n:
                sel.want([r for quantile in SPAN_QUANTILES for r in _quantile_wanted(sel.n, quantile)])
        self._planned = True

    def collect_part(self, parts: Mapping[str, pd.DataFrame]) -> None:
        """Pass 2 over one part of every solution, in any order of the parts (after :meth:`plan`)."""
        if not self._planned:
            raise RuntimeError("plan() comes between the passes")
        first = self._one(parts)
        masks = self._masks(first)
        n_fov = first["n_fov"].to_numpy()
        span = first["span_days"].to_numpy() if "span_days" in first else None
        for lab in self.labels:
            inside, err = parts[lab]["inside"].to_numpy(), _errors(parts[lab])
            if err is None or lab not in self.ranked:
                continue
            for (s, g), m in masks.items():
                self.cells[lab, s, g].errors.collect(err[m][inside[m] >= 0])
        if span is not None:
            for g in self.g_classes:
                self.spans[g].collect(span[masks["<=4", g] & (n_fov >= 1)])

    # ----------------------------------------------------------------- results
    def cell_statistics(self, label: str, subset: str, g: float) -> tuple:
        """``(n_stars, n_valid, n_inside, fraction, fraction_lo, fraction_hi, percentile,
        percentile_lo, percentile_hi)`` of one cell (:func:`~.primary_table.cell_statistics`'s
        numbers: the percentile NaN if an error is not finite, its interval over the finite ones)."""
        cell = self.cells[label, subset, float(g)]
        frac, lo, hi = fraction_from_counts(cell.n_inside, cell.n_valid)
        sel, n = cell.errors, cell.errors.n
        q = error_percentile(self.confidence)
        p = plo = phi = float("nan")
        if n:
            if not sel.n_nonfinite:
                p = _quantile(sel, np.true_divide(q, 100))
            i, j = cell.interval_ranks
            plo = sel.value(i) if i >= 0 else float("nan")
            phi = sel.value(j) if j < n else float("nan")
        return cell.n_stars, cell.n_valid, cell.n_inside, frac, lo, hi, p, plo, phi

    def factor_counts(self, subset: str, g: float) -> list[tuple[int, int]]:
        """``(n_valid, n_inside)`` per factor k (ascending) of one cell."""
        return [(self.cells[lab, subset, float(g)].n_valid, self.cells[lab, subset, float(g)].n_inside)
                for lab in self.factors.values()]

    def factor_crossing(self, subset: str, g: float, *, n_resamples: int, rng: np.random.Generator) -> tuple:
        """``(n_valid, k_min, flag, k_lo, k_hi)`` of one cell (:mod:`~.primary_factor`)."""
        ks = np.array(list(self.factors), dtype=float)
        counts = self.factor_counts(subset, g)
        n_val = np.array([c[0] for c in counts], dtype=float)
        if not n_val.any():
            return 0, float("nan"), "no_stars", float("nan"), float("nan")
        with np.errstate(invalid="ignore", divide="ignore"):
            frac = np.array([c[1] for c in counts], dtype=float) / n_val
        k_min, flag = sigma_f90_from_curve(ks, frac, self.confidence)
        lo, hi = pattern_interval(ks, self.patterns[subset, float(g)], self.confidence, "log", n_resamples, rng)
        return int(n_val.max()), k_min, flag, lo, hi

    def span_summary(self, g: float) -> tuple[np.ndarray, float] | None:
        """The <= 4 transit stars of class ``g`` with live transits: (quantiles
        :data:`SPAN_QUANTILES` of their spans [d], fraction within a day); None without any."""
        sel = self.spans[float(g)]
        n, within = sel.n + sel.n_nonfinite, self.within_a_day[float(g)]
        if not n:
            return None
        q = np.full(len(SPAN_QUANTILES), np.nan)
        if sel.n:
            q = np.array([_quantile(sel, quantile) for quantile in SPAN_QUANTILES])
        return q, within / n


def reduce_parts(read: Callable[[int], Mapping[str, pd.DataFrame]], n_parts: int, reduction: TableReduction
                 ) -> TableReduction:
    """``reduction`` after both passes over the ``n_parts`` parts ``read(j)`` gives (part j of
    every solution it reduces)."""
    for j in range(n_parts):
        reduction.count_part(read(j))
    reduction.plan()
    for j in range(n_parts):
        reduction.collect_part(read(j))
    return reduction

