"""The epochs that place the attitude knots (``experiment.primary.knot_transits``), kept on a
Dask cluster's workers.

With ``knot_transits`` the solver's knots are placed by the solution's live FoV transits: in
each attitude segment, its first and last epoch, and the quantiles of its epochs at equal
counts (``knot_rule='counts'``) or its epochs counted in bins of the knot interval
(``'uniform'``; :class:`~mcsweep.solver.attitude_spline.AttitudeSpline`). On one machine those come
from one sorted array (8 bytes per transit, 2e7 transits at the paper's sizes); on a cluster
the epochs stay sorted per partition of the table of stars where they were found, and
:class:`ClusterEpochs` answers what the spline asks
(:class:`~mcsweep.solver.attitude_spline.SortedEpochs`: counts below given times, values at
given ranks) with tasks there: the knots are the same bits, and the driver holds counts per
bin of time and the knots, not the epochs.
"""

from __future__ import annotations

import operator

import numpy as np

__all__ = ["ClusterEpochs", "live_epochs"]


def live_epochs(summary: dict, transits: dict, dead, first: int) -> np.ndarray:
    """The live epochs of a partition's solved stars, sorted (the knots' data, ``knot_transits``)."""
    live = ~dead.is_dead(transits["t"])
    return np.sort(transits["t"][live & summary["solved"][transits["star"] - first]])


def _count_below(epochs: np.ndarray, x: np.ndarray, side: str) -> np.ndarray:
    return np.searchsorted(epochs, x, side)


def _bin_counts(epochs: np.ndarray, edges: np.ndarray) -> np.ndarray:
    return np.bincount(np.searchsorted(edges, epochs, "right") - 1, minlength=edges.size - 1)


def _split_epochs(epochs: np.ndarray, edges: np.ndarray) -> list:
    cuts = np.searchsorted(epochs, edges, "left")
    return [epochs[a:b] for a, b in zip(cuts[:-1], cuts[1:])]


def _bucket_values(local_ranks: np.ndarray, *pieces) -> np.ndarray:
    return np.sort(np.concatenate(pieces))[local_ranks]


class ClusterEpochs:
    """The knots' epochs (``knot_transits``) sorted per partition on the workers, answering
    :class:`~mcsweep.solver.attitude_spline.SortedEpochs`' questions without meeting in one
    process: counts below a time are sums over the partitions; values at ranks come from
    buckets of time of at most :attr:`BUCKET` epochs (cut at bins whose counts the partitions
    give), each sorted on one worker, which returns only the wanted ranks' values. The driver
    holds the bins' counts and the ranks: the knots' size, not the transits'."""

    BINS = 4096
    BUCKET = 1_000_000

    def __init__(self, client, futures: list, start_jd: float, end_jd: float):
        self.client, self.futures = client, futures
        inner = np.linspace(start_jd, end_jd, self.BINS + 1)[1:-1]
        self.edges = np.concatenate([[-np.inf], inner, [np.inf]])
        self.counts = sum(client.gather([client.submit(_bin_counts, f, self.edges, pure=False) for f in futures]),
                          np.zeros(self.BINS, dtype=np.int64))

    @property
    def size(self) -> int:
        return int(self.counts.sum())

    def searchsorted(self, x, side: str) -> np.ndarray:
        from distributed import as_completed

        # summed as the partitions answer (integers: the order does not matter), so the driver
        # holds one answer at a time: with knot_rule='uniform' an answer is a count per bin of
        # the knot interval, ~1e6 at the paper's sizes
        x = np.asarray(x, dtype=float)
        total = np.zeros(x.shape, dtype=np.int64)
        for fut in as_completed([self.client.submit(_count_below, f, x, side, pure=False) for f in self.futures]):
            total += fut.result()
            fut.release()
        return total

    def values(self, ranks) -> np.ndarray:
        ranks = np.asarray(ranks, dtype=np.int64)
        client = self.client
        bounds, total = [0], 0  # buckets of consecutive bins (a bin over BUCKET: a bucket of its own)
        for i, c in enumerate(self.counts.tolist()):
            if total and total + c > self.BUCKET:
                bounds.append(i)
                total = 0
            total += c
        bounds.append(self.BINS)
        first_rank = np.concatenate([[0], np.cumsum(self.counts)])[bounds]
        bucket = np.searchsorted(first_rank, ranks, "right") - 1
        wanted = np.unique(bucket)
        edges = self.edges[bounds]
        splits = [client.submit(_split_epochs, f, edges, pure=False) for f in self.futures]
        tasks = {int(k): client.submit(_bucket_values, ranks[bucket == k] - first_rank[k],
                                       *[client.submit(operator.getitem, s, int(k), pure=False) for s in splits],
                                       pure=False) for k in wanted}
        out = np.empty(ranks.size)
        for k, fut in tasks.items():
            out[bucket == k] = fut.result()
        return out
