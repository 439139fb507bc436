"""The table of a global solution's stars kept on a Dask cluster, in sky order.

A primary solution holds every class in one sky order (:func:`~.global_classes.sky_order`:
by HEALPix level-12 nested pixel, a pixel's stars in the classes' order, each class in its
own). On one machine that is a sort of the whole table; on a cluster the table never meets
in one process:

1. each class (a task drawing it from the galaxy model, or a catalogue's class sent from
   the driver) becomes :func:`~.global_classes.class_table` with its pixels, stably sorted by
   pixel, on a worker; back to the driver come only its counts per coarse pixel (level
   :data:`COARSE_LEVEL`, 49152 of them);
2. the driver cuts the sky into partitions of about ``target`` stars at coarse-pixel
   boundaries (their sizes are sums of those counts, known without the stars);
3. each partition is the concatenation of the classes' pieces in its pixel range, in class
   order, stably sorted by pixel: the rows of the whole table's sort, bit for bit (a stable
   sort of a concatenation is the stable sorts of its pixel ranges, one after another).

A worker lost with a partition: the scheduler does not keep the lineage of the released
tasks it came from, so :meth:`SkyPartitions.ensure` makes every partition again from the
classes (drawn on the workers from their seeds, or read there from the catalogue): the
same bits.
"""

from __future__ import annotations

import dataclasses
import operator
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from ..global_solution.classes import SKY_ORDER_LEVEL, class_table, sky_pixels

__all__ = ["COARSE_LEVEL", "SkyPartitions", "alive", "sky_partitions", "table_partitions"]

#: HEALPix level of the counts by which the sky is cut into partitions: 49152 pixels of
#: 0.84 square degrees, fine enough for partitions of a few thousand stars anywhere.
COARSE_LEVEL = 6
_SHIFT = 2 * (SKY_ORDER_LEVEL - COARSE_LEVEL)
_N_COARSE = 12 * 4 ** COARSE_LEVEL


def _keyed(drawn, key: int) -> pd.DataFrame:
    """A class (a frame, or :func:`~.global_classes.draw_class`'s ``(key, stars, warnings)``) as
    the solution's table with its pixels (column ``_pix``), stably sorted by pixel."""
    stars = drawn[1] if isinstance(drawn, tuple) else drawn
    table = class_table(stars, key)
    pix = sky_pixels(table["ra"].to_numpy(), table["dec"].to_numpy())
    order = np.argsort(pix, kind="stable")
    table = table.iloc[order].reset_index(drop=True)
    table["_pix"] = pix[order]
    return table


def _coarse_counts(table: pd.DataFrame) -> np.ndarray:
    return np.bincount(table["_pix"].to_numpy() >> _SHIFT, minlength=_N_COARSE)


def _split(table: pd.DataFrame, edges: np.ndarray) -> list:
    """The pieces of a sorted class table between consecutive pixel ``edges``."""
    cuts = np.searchsorted(table["_pix"].to_numpy(), edges)
    return [table.iloc[a:b] for a, b in zip(cuts[:-1], cuts[1:])]


def _merge(*pieces) -> pd.DataFrame:
    """One partition: the classes' pieces in class order, stably sorted by pixel (module notes)."""
    table = pd.concat(pieces, ignore_index=True)
    order = np.argsort(table["_pix"].to_numpy(), kind="stable")
    return table.iloc[order].drop(columns="_pix").reset_index(drop=True)


def _warnings(drawn) -> list:
    return drawn[2] if isinstance(drawn, tuple) else []


@dataclasses.dataclass
class SkyPartitions:
    """The solution's table of stars as partitions on the workers, in sky order.

    ``futures[p]``: a future of partition ``p``'s frame (:data:`~.global_classes.STAR_COLUMNS`
    and ``class_key``); ``first[p]``: its first star in the whole table; ``sizes[p]``: its
    stars; ``remake()``: new futures of every partition (the same frames).
    """

    futures: list
    first: np.ndarray
    sizes: np.ndarray
    remake: Callable = dataclasses.field(default=None, repr=False)

    @property
    def n_stars(self) -> int:
        return int(self.sizes.sum())

    def __len__(self) -> int:
        return len(self.futures)

    def ensure(self) -> bool:
        """Make every partition again if a lost worker took one (module notes); True if so."""
        if all(alive(f) for f in self.futures):
            return False
        self.futures = self.remake()
        return True


def alive(future) -> bool:
    """Whether a future's result is there or on its way (not lost with a worker)."""
    return future.status in ("pending", "finished")


def sky_partitions(client, classes: Sequence[tuple[int, Callable]], target: int) -> tuple[SkyPartitions, list]:
    """The table of ``classes`` on the workers of ``client`` in sky order, in partitions of
    about ``target`` stars (module notes), and the classes' warnings ``(category, message)``
    for the caller to repeat.

    ``classes[i] = (key, make)``: the class key and ``make()``, a new future of the class (a
    frame, or :func:`~.global_classes.draw_class`'s result), called again after a loss."""
    made = [(key, make()) for key, make in classes]
    keyed = [client.submit(_keyed, fut, key, pure=False) for key, fut in made]
    caught = [w for ws in client.gather([client.submit(_warnings, fut, pure=False) for _, fut in made]) for w in ws]
    counts = sum(client.gather([client.submit(_coarse_counts, k, pure=False) for k in keyed]),
                 np.zeros(_N_COARSE, dtype=np.int64))
    cum = np.cumsum(counts)
    total = int(cum[-1]) if cum.size else 0
    n_parts = max(1, -(-total // max(int(target), 1)))
    # cut after the coarse pixel where the running count reaches each multiple of the target
    cuts = np.unique(np.searchsorted(cum, np.arange(1, n_parts) * total / n_parts, side="left") + 1)
    coarse_edges = np.concatenate([[0], cuts[(cuts > 0) & (cuts < _N_COARSE)], [_N_COARSE]]).astype(np.int64)
    edges = coarse_edges << _SHIFT
    sizes = np.array([counts[a:b].sum() for a, b in zip(coarse_edges[:-1], coarse_edges[1:])], dtype=np.int64)
    keep = sizes > 0
    first = np.concatenate([[0], np.cumsum(sizes[keep])[:-1]]).astype(np.int64)
    del made

    def build(keyed_futures) -> list:
        splits = [client.submit(_split, k, edges, pure=False) for k in keyed_futures]
        pieces = [[client.submit(operator.getitem, s, p, pure=False) for s in splits] for p in np.flatnonzero(keep)]
        return [client.submit(_merge, *ps, pure=False) for ps in pieces]

    def remake() -> list:
        return build([client.submit(_keyed, make(), key, pure=False) for key, make in classes])

    futures = build(keyed)
    del keyed
    return SkyPartitions(futures=futures, first=first, sizes=sizes[keep], remake=remake), caught


def _frame_part(frame: pd.DataFrame) -> pd.DataFrame:
    return frame


def table_partitions(client, stars: pd.DataFrame, target: int) -> SkyPartitions:
    """A table of stars the driver holds (columns :data:`~.global_classes.STAR_COLUMNS` and
    ``class_key``), in its own order, as partitions of ``target`` stars on the cluster: each
    part sent inside its task (so a lost one is made again from the graph), for tests and
    small tables; a run's classes are drawn and put in sky order on the workers
    (:func:`sky_partitions`)."""
    n = len(stars)
    bounds = list(range(0, n, max(int(target), 1))) + [n]
    pieces = [stars.iloc[a:b].reset_index(drop=True) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]

    def make() -> list:
        return [client.submit(_frame_part, piece, pure=False) for piece in pieces]

    sizes = np.array([len(piece) for piece in pieces], dtype=np.int64)
    return SkyPartitions(futures=make(), first=np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64),
                         sizes=sizes, remake=make)
