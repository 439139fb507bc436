"""Solve Gaia DR4 epoch astrometry with and without the prior (``mcsweep-prior solve EPOCH_FILE``).

Input: an epoch-astrometry file of the Gaia archive or of DPAC (any format and either column
convention, :mod:`mcsweep.astrometry.epoch_astrometry`) and a sources table, an extract of
``gaia_source`` with ``source_id``, ``ra``, ``dec`` [deg] and ``phot_g_mean_mag``, and
``bp_rp`` or ``phot_bp_mean_mag``/``phot_rp_mean_mag`` if present (for a prior with a colour
axis). Each source's AL CCD observations give its normal equations as AGIS's source update
forms them (:mod:`mcsweep.astrometry.source_update`: the file's parallax factor,
barycentric time, the CCDs AGIS used, weights with AGIS's excess noise; five parameters, or
DR4's six with the constrained pseudo-colour), at the reference epoch J2017.5 (TCB) unless
told otherwise. From them every source gets the columns of
:func:`mcsweep.prior.solutions.solutions_table` (its ``no_prior_*`` columns are the
source update without prior; ``solution`` says which to use), plus ``model``, ``n_ccd_al``,
``excess_noise_mas`` and, for 6p, ``pseudocolour`` and ``pseudocolour_error`` [nm^-1].

Large inputs. The file is read in batches of rows (Parquet by row groups, CSV in chunks) and
each batch is solved on its own, so memory is flat in the number of sources; a ``run``
callable (the execution backend of ``mcsweep.runtime.execution``, given by the command)
solves batches in parallel, in a window of a few batches at a time. A source's rows may not
be split between batches: the rows of the batch's last source are carried into the next
batch, so the file must hold each source's rows together (the archive's files do; a file
that fits one batch may be in any order). A source seen again after its batch was solved is
refused in one line naming it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import pandas as pd

from ..astrometry.epoch_astrometry import COLUMNS, OPTIONAL_COLUMNS, ccd_observations, is_epoch_astrometry
from ..astrometry.source_update import check_model, source_normals
from ..errors import UserInputError
from ..tables import TableChunk, detect_format, integer_ids, iter_tables, read_table
from ..tables.read import arrow_batches, parquet_rows
from .columns import finite_column, source_bp_rp
from .epochs import reference_epoch_jd
from .model import Prior
from .solutions import check_factor, solutions_table

__all__ = ["BATCH_ROWS", "RowRange", "SourceTable", "read_sources", "looks_like_epoch_astrometry", "epoch_batches",
           "solve_epoch_batch", "solve_epoch_file", "epoch_files",
           "EPOCH_SOURCE_COLUMNS", "has_source_columns", "sources_of_batch"]

#: FoV transits per batch (about 80 MB of per-CCD arrays at 10 CCDs and 10 columns).
BATCH_ROWS = 100_000
#: Batches in flight per worker when solving in parallel (bounded memory, workers kept busy).
_WINDOW_PER_WORKER = 2


@dataclass(frozen=True)
class SourceTable:
    """The sources table, sorted by ``source_id`` (int64, exact)."""

    source_id: np.ndarray
    ra: np.ndarray
    dec: np.ndarray
    phot_g_mean_mag: np.ndarray
    bp_rp: np.ndarray
    name: str

    def rows_of(self, ids: np.ndarray, epoch_file: str) -> np.ndarray:
        """Index of each of ``ids`` in this table; UserInputError naming the first one absent
        or without a finite ra, dec and G."""
        if not self.source_id.size:
            raise UserInputError(f"{self.name} has no rows; expected ra, dec and phot_g_mean_mag for every source "
                                 f"of {epoch_file}")
        where = np.searchsorted(self.source_id, ids)
        found = (where < self.source_id.size) & (self.source_id[np.minimum(where, self.source_id.size - 1)] == ids)
        if not found.all():
            raise UserInputError(f"{epoch_file}: source_id {ids[~found][0]} has no row in {self.name}; expected "
                                 "ra, dec and phot_g_mean_mag for every source of the epoch file")
        return where

    def subset(self, ids: np.ndarray, epoch_file: str) -> "SourceTable":
        rows = self.rows_of(np.unique(ids), epoch_file)
        return SourceTable(self.source_id[rows], self.ra[rows], self.dec[rows], self.phot_g_mean_mag[rows],
                           self.bp_rp[rows], self.name)


def read_sources(path) -> SourceTable:
    """The ``--sources`` table (module notes), checked: exact ids, once each, numeric ra, dec, G
    (finite for every source that is solved)."""
    t = read_table(path, what="--sources")
    name = Path(path).name
    cols = {k: t.find(k) for k in ("source_id", "ra", "dec", "phot_g_mean_mag")}
    missing = [k for k, v in cols.items() if v is None]
    if missing:
        raise UserInputError(f"{name}: columns {t.names[:12]} lack {missing}; expected a gaia_source extract with "
                             "source_id, ra, dec [deg] and phot_g_mean_mag")
    ids = integer_ids(t[cols["source_id"]], cols["source_id"], name)
    order = np.argsort(ids, kind="stable")
    ids = ids[order]
    dup = ids[1:][ids[1:] == ids[:-1]]
    if dup.size:
        raise UserInputError(f"{name}: source_id {dup[0]} appears twice; expected one row per source")
    # NaN allowed here (gaia_source has sources without G): refused only for a source that
    # is solved (SourceTable.rows_of).
    vals = {}
    for k in ("ra", "dec", "phot_g_mean_mag"):
        try:
            vals[k] = np.asarray(t[cols[k]], dtype=float)[order]
        except (TypeError, ValueError):
            raise UserInputError(f"{name}: column {cols[k]} has non-numeric values; expected numbers") from None
    if np.any(np.abs(vals["dec"]) > 90):
        raise UserInputError(f"{name}: column {cols['dec']} has values beyond +-90; expected degrees")
    colour = [c for c in (t.find("bp_rp"), t.find("phot_bp_mean_mag"), t.find("phot_rp_mean_mag")) if c]
    bp_rp = source_bp_rp(pd.DataFrame({c: t[c] for c in colour}, index=np.arange(len(t))), name)[order]
    return SourceTable(ids, vals["ra"], vals["dec"], vals["phot_g_mean_mag"], bp_rp, name)


def looks_like_epoch_astrometry(path) -> bool:
    """Whether the table at ``path`` (or a directory's first table) is epoch astrometry (from its first rows only)."""
    for chunk in iter_tables(epoch_files(path)[0], what="observations", batch_rows=16):
        return is_epoch_astrometry(chunk)
    return False


def _source_ids(chunk: TableChunk) -> np.ndarray:
    name = chunk.find(*COLUMNS["source_id"])
    if name is None:
        raise UserInputError(f"{chunk.source}: not Gaia epoch astrometry, lacks source_id (or sourceId); expected "
                             "the columns of the archive's epoch_astrometry")
    return integer_ids(chunk[name], name, chunk.source)


@dataclass(frozen=True)
class RowRange:
    """Rows ``start:stop`` of a Parquet epoch file, read by whoever solves them (a worker reads
    its own rows: nothing but the range travels to it)."""

    path: str
    start: int
    stop: int
    columns: tuple | None = None

    def load(self) -> TableChunk:
        return parquet_rows(self.path, self.start, self.stop, columns=self.columns, what="epoch astrometry")


def epoch_files(path) -> list[Path]:
    """``path`` itself, or the table files in the directory ``path`` (sorted by name)."""
    path = Path(path)
    if not path.is_dir():
        return [path]
    found = []
    for f in sorted(path.iterdir()):
        if f.is_file():
            try:
                detect_format(f)
            except UserInputError:
                continue  # README, checksums and the like next to the data
            found.append(f)
    if not found:
        raise UserInputError(f"{path}: a directory without table files; expected Gaia epoch astrometry files "
                             "(CSV, ECSV, FITS, VOTable or Parquet)")
    return found


def epoch_batches(path, *, batch_rows: int = BATCH_ROWS) -> Iterator[tuple[TableChunk | RowRange, np.ndarray]]:
    """Batches of the epoch file, or of each file of a directory, that hold whole sources, with
    each row's source_id (module notes). A source is in one batch of one file only.

    A Parquet file is scanned by its source_id column alone and handed out as
    :class:`RowRange` s; other formats as the batches' rows themselves.
    """
    done: list[np.ndarray] = []
    for f in epoch_files(path):
        f = f.resolve()  # a worker elsewhere (Dask) reads the same file by this path
        if detect_format(f, what="epoch astrometry") == "parquet":
            yield from _parquet_ranges(f, batch_rows, done)
        else:
            yield from _chunk_batches(f, batch_rows, done)


def _chunk_batches(path: Path, batch_rows: int, done: list) -> Iterator[tuple[TableChunk, np.ndarray]]:
    carry: TableChunk | None = None
    source = path.name
    for chunk in iter_tables(path, what="epoch astrometry", batch_rows=batch_rows):
        if not len(chunk):
            continue
        chunk = TableChunk.concat([carry, chunk]) if carry is not None else chunk
        ids = _source_ids(chunk)
        last = ids == ids[-1]
        if last.all():
            carry = chunk
            continue
        carry = chunk.take(last)
        ready = chunk.take(~last)
        yield ready, _checked_once(ids[~last], done, source)
    if carry is not None:
        ids = _source_ids(carry)
        yield carry, _checked_once(ids, done, source)


def _parquet_ranges(path: Path, batch_rows: int, done: list) -> Iterator[tuple[RowRange, np.ndarray]]:
    schema, _ = arrow_batches(path, 1, what="epoch astrometry")
    name = next((n for n in schema.names if n.lower() in ("source_id", "sourceid")), None)
    if name is None:
        raise UserInputError(f"{path.name}: not Gaia epoch astrometry, lacks source_id (or sourceId); expected "
                             "the columns of the archive's epoch_astrometry")
    # Only the columns the source update reads (a file has ~14, of which 10 are used).
    wanted = {n.lower() for pair in (*COLUMNS.values(), *OPTIONAL_COLUMNS.values()) for n in pair}
    wanted |= {"used_by_agis_al.1", "used_by_agis_ac", *EPOCH_SOURCE_COLUMNS}
    columns = tuple(n for n in schema.names if n.lower() in wanted)
    batches = iter_tables(path, what="epoch astrometry", batch_rows=batch_rows, columns=[name])
    first = next((c for c in batches if len(c)), None)
    if first is None:
        return
    second = next((c for c in batches if len(c)), None)
    if second is None:  # the whole file is one batch: its rows may be in any order
        ids = integer_ids(first[name], name, path.name)
        yield RowRange(str(path), 0, ids.size, columns), _checked_once(ids, done, path.name)
        return
    pending: list[np.ndarray] = []
    start = 0  # first row of the pending ids
    for chunk in _chain([first, second], batches):
        pending.append(integer_ids(chunk[name], name, path.name))
        ids = np.concatenate(pending)
        cut = int(np.flatnonzero(ids == ids[-1])[0])  # the last source may go on in the next rows
        if cut == 0:
            pending = [ids]
            continue
        yield RowRange(str(path), start, start + cut, columns), _checked_once(ids[:cut], done, path.name)
        start += cut
        pending = [ids[cut:]]
    if pending and pending[0].size:
        ids = np.concatenate(pending)
        yield RowRange(str(path), start, start + ids.size, columns), _checked_once(ids, done, path.name)


def _chain(head, tail):
    yield from head
    yield from (c for c in tail if len(c))


def _checked_once(ids: np.ndarray, done: list[np.ndarray], source: str) -> np.ndarray:
    """``ids``, after checking that none of its sources was in an earlier batch (8 bytes per source kept)."""
    unique = np.unique(ids)
    for earlier in done:
        pos = np.searchsorted(earlier, unique)
        seen = (pos < earlier.size) & (earlier[np.minimum(pos, earlier.size - 1)] == unique)
        if seen.any():
            raise UserInputError(f"{source}: the rows of source_id {unique[seen][0]} are not together (it appears "
                                 "again after other sources); expected each source's rows in one block, as the "
                                 "archive writes them (sort the file by source_id)")
    done.append(unique)
    return ids


#: Columns of the DR4 epoch-astrometry format (the June 2026 public pre-release) that hold a
#: source's reference position [deg] and G per transit: with them no sources table is needed.
EPOCH_SOURCE_COLUMNS = ("ra0", "dec0", "g_mag")


def has_source_columns(path) -> bool:
    """Whether the epoch file (or a directory's first file) carries ``ra0``, ``dec0`` and ``g_mag``."""
    for chunk in iter_tables(epoch_files(path)[0], what="epoch astrometry", batch_rows=16):
        return all(chunk.find(c) is not None for c in EPOCH_SOURCE_COLUMNS)
    return False


def sources_of_batch(chunk: TableChunk) -> SourceTable:
    """Each source's reference position (``ra0``, ``dec0`` of its first row) and G (the median of
    its rows' finite ``g_mag``) from an epoch file that carries them (DR4's format)."""
    names = {c: chunk.find(c) for c in EPOCH_SOURCE_COLUMNS}
    if None in names.values():
        raise UserInputError(f"{chunk.source}: has no {', '.join(c for c, v in names.items() if v is None)} (other "
                             "files of the input have them); expected --sources SOURCES for files without them")
    ids = _source_ids(chunk)
    order = np.argsort(ids, kind="stable")
    ids_sorted = ids[order]
    first = np.r_[True, ids_sorted[1:] != ids_sorted[:-1]]
    starts = np.flatnonzero(first)
    vals = {c: finite_column(chunk[names[c]], names[c], chunk.source)[order]
            for c in ("ra0", "dec0")}
    g = np.asarray(chunk[names["g_mag"]], dtype=float)[order]
    frame = pd.DataFrame({"s": np.repeat(np.arange(starts.size), np.diff(np.r_[starts, ids.size])), "g": g})
    g_src = frame.groupby("s")["g"].median().to_numpy()
    bad = ~np.isfinite(g_src)
    if bad.any():
        raise UserInputError(f"{chunk.source}: source_id {ids_sorted[starts][bad][0]} has no finite {names['g_mag']}; "
                             "expected G for every source (or give --sources)")
    return SourceTable(ids_sorted[starts], vals["ra0"][starts], vals["dec0"][starts], g_src,
                       np.full(starts.size, np.nan), chunk.source)


def solve_epoch_batch(chunk: TableChunk | RowRange, sources: SourceTable | None, prior: Prior, *, model: str,
                      factor: float, confidence: float | None, reference_epoch: float | None) -> pd.DataFrame:
    """The solutions table (module notes) of the sources of one batch of an epoch file;
    ``sources`` None: from the file's own ``ra0``, ``dec0``, ``g_mag`` (:func:`sources_of_batch`)."""
    if isinstance(chunk, RowRange):
        chunk = chunk.load()
    if sources is None:
        sources = sources_of_batch(chunk)
    obs = ccd_observations(chunk, need_colour=(model == "6p"))
    all_ids = np.unique(_source_ids(chunk))
    sn = source_normals(obs, model=model, reference_epoch_jd=reference_epoch)
    if sn.source_id.size != all_ids.size:
        lost = np.setdiff1d(all_ids, sn.source_id)[0]
        raise UserInputError(f"{chunk.source}: source_id {lost} has no usable AL CCD observation (none with "
                             "used_by_agis_al true and time, barycentric correction, scan angle, centroid and a "
                             "positive error present); expected at least one per source")
    src = sources.subset(sn.source_id, chunk.source)
    table = solutions_table(sn.source_id, src.ra, src.dec, src.phot_g_mean_mag, src.bp_rp, sn.N, sn.b,
                            n_transits=sn.n_transits, reference_epoch_jd=sn.reference_epoch_jd,
                            n_visibility_periods=sn.n_visibility_periods, time_span_yr=sn.time_span_yr,
                            prior=prior, factor=factor, confidence=confidence)
    table.insert(1, "model", model)
    table.insert(table.columns.get_loc("n_transits") + 1, "n_ccd_al", sn.n_ccd)
    table["excess_noise_mas"] = sn.excess_noise_mas
    if sn.pseudocolour is not None:
        table["pseudocolour"] = sn.pseudocolour
        table["pseudocolour_error"] = sn.pseudocolour_error
    return table


def _indexed(fn, item):
    i, batch = item
    return i, fn(*batch)


def solve_epoch_file(epoch_path, sources_path, prior: Prior, *, model: str = "5p", factor: float = 1.0,
                     confidence: float | None = None, reference_epoch: str = "J2017.5",
                     batch_rows: int = BATCH_ROWS, run: Callable | None = None,
                     n_workers: int = 1) -> Iterator[pd.DataFrame]:
    """The solutions of every source of ``epoch_path``, one table per batch, in file order.

    Parameters
    ----------
    epoch_path, sources_path : path-like
        ``epoch_path`` may be a directory: its table files are solved one after the other.
        ``sources_path`` None: each source's position and G from the file's ``ra0``, ``dec0``
        and ``g_mag`` (DR4's format carries them).
    prior : Prior
        The prior (:meth:`Prior.paper <mcsweep.prior.Prior.paper>` or a run's fit).
    model : {'5p', '6p'}
        Five parameters, or six with AGIS's pseudocolour eliminated.
    factor : float
        K: the prior is K sigma_F90 (Sect. 3.3).
    confidence : float or None
        P of the ellipse; default the prior's own P.
    reference_epoch : str
        'J2017.5' (DR4's, default), another Julian year or ISO date (TCB), or 'star_mean'
        (each source's mean epoch of observation, Sect. 2.1).
    batch_rows : int
        FoV transits read per batch.
    run : callable, optional
        ``run(fn, items)`` yielding ``fn(item)`` in completion order (the command's execution
        backend); None solves the batches here, one after the other.
    n_workers : int
        Workers behind ``run``: the window of batches in flight is a few per worker.

    Yields
    ------
    pandas.DataFrame
        The solutions of a batch's sources (the columns of
        :func:`mcsweep.prior.solutions.solutions_table`), in file order.

    Examples
    --------
    >>> from importlib.resources import files
    >>> data = files('mcsweep') / 'data' / 'epoch_astrometry'
    >>> import pandas as pd
    >>> from mcsweep.prior import Prior
    >>> from mcsweep.prior.epoch_solve import solve_epoch_file
    >>> batches = solve_epoch_file(data / 'sample_epoch_astrometry.parquet',
    ...                            data / 'sample_sources.csv', Prior.paper())
    >>> solved = pd.concat(batches)
    >>> len(solved), bool(solved['prior_ok'].all())
    (10, True)
    """
    check_model(model)
    check_factor(factor)
    epoch = None if str(reference_epoch) == "star_mean" else reference_epoch_jd(reference_epoch)
    if sources_path is None and not has_source_columns(epoch_path):
        raise UserInputError(f"{Path(epoch_path).name} is Gaia epoch astrometry without ra0, dec0 and g_mag; "
                             "expected --sources SOURCES (a gaia_source extract: source_id, ra, dec, "
                             "phot_g_mean_mag)")
    sources = None if sources_path is None else read_sources(sources_path)
    name = Path(epoch_path).name
    solve = partial(solve_epoch_batch, prior=prior, model=model, factor=factor, confidence=confidence,
                    reference_epoch=epoch)

    def items():
        for chunk, ids in epoch_batches(epoch_path, batch_rows=batch_rows):
            yield chunk, (None if sources is None else sources.subset(ids, name))

    if run is None:
        for chunk, src in items():
            yield solve(chunk, src)
        return
    window = max(1, n_workers * _WINDOW_PER_WORKER)
    pending: dict[int, pd.DataFrame] = {}
    next_out = 0
    batch: list = []
    fn = partial(_indexed, solve)
    for i, item in enumerate(items()):
        batch.append((i, item))
        if len(batch) == window:
            for j, table in run(fn, batch):
                pending[j] = table
            batch = []
            while next_out in pending:
                yield pending.pop(next_out)
                next_out += 1
    if batch:
        for j, table in run(fn, batch):
            pending[j] = table
    while next_out in pending:
        yield pending.pop(next_out)
        next_out += 1
