"""Read a user's table file, whole or in batches of rows, as plain numpy columns.

One reader for every table a user gives mcsweep: catalogues (``population=catalogue``),
catalogues to annotate, observations and sources for ``mcsweep-prior solve``, Gaia epoch
astrometry, and a sweep's own run tables. Formats are those of ``mcsweep.tables.formats``; CSV may be
gzipped. Parquet and CSV are read in batches of rows (Parquet by its row groups, with
pyarrow's read-ahead off so memory stays flat whatever the file's size); FITS, VOTable and
ECSV are read whole by astropy and handed out in slices.

A column comes out as

* a 1-D array for scalar columns (masked values: NaN for floats, a masked integer column
  becomes float with NaN);
* a 2-D array (rows x elements) for fixed-length array columns;
* a ``Ragged`` for variable-length array columns (VOTable/FITS variable arrays,
  Parquet lists), or an object array of strings for arrays written as text, as the
  archive's CSV does (``"(1.0, 2.0)"``): ``as_ragged`` turns any of these into one form.

Identifier columns (names ending in ``id``: ``source_id``, ``sourceId``, ``transit_id``)
are read from CSV as text, never through float64, so a Gaia ``source_id`` (up to ~7e18,
beyond float64's 2**53) is kept exact; :func:`mcsweep.tables.integer_ids` checks and
converts them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from ..errors import UserInputError
from .formats import ASTROPY_FORMAT, detect_format

__all__ = ["Ragged", "TableChunk", "read_table", "iter_tables", "as_ragged", "is_identifier", "arrow_batches",
           "astropy_table", "csv_batches", "parquet_rows", "row_starts", "ramp"]

#: Rows per batch when a caller does not say (about 25 MB of float64 at 12 columns).
DEFAULT_BATCH_ROWS = 262_144


@dataclass(frozen=True)
class Ragged:
    """A column of variable-length arrays: the elements of all rows in order, and each row's count."""

    values: np.ndarray
    lengths: np.ndarray

    def __len__(self) -> int:
        return int(self.lengths.size)

    @property
    def starts(self) -> np.ndarray:
        """Index in ``values`` of each row's first element."""
        return row_starts(self.lengths)

    def element_index(self, rows) -> np.ndarray:
        """Indices in ``values`` of the elements of ``rows``, row after row."""
        rows = np.asarray(rows, dtype=np.int64)
        lengths = self.lengths[rows]
        return np.repeat(self.starts[rows], lengths) + ramp(lengths)

    def take(self, rows: np.ndarray) -> "Ragged":
        """The rows ``rows`` (indices) of this column, in that order."""
        return Ragged(self.values[self.element_index(rows)], self.lengths[rows])


def row_starts(lengths) -> np.ndarray:
    """Start of each row in the concatenation of rows of ``lengths`` elements."""
    lengths = np.asarray(lengths, dtype=np.int64)
    return np.cumsum(lengths) - lengths


def ramp(lengths) -> np.ndarray:
    """0 .. n - 1 for each n of ``lengths``, concatenated (an element's place in its row)."""
    lengths = np.asarray(lengths, dtype=np.int64)
    return np.arange(int(lengths.sum()), dtype=np.int64) - np.repeat(row_starts(lengths), lengths)


def is_identifier(name: str) -> bool:
    """Whether a column holds integer identifiers that must never pass through float64."""
    low = str(name).lower()
    return low.endswith("_id") or low in ("sourceid", "transitid", "solutionid", "hip", "id")


class TableChunk:
    """Some rows of a table: columns by name (:mod:`module notes <mcsweep.tables.read>`)
    with their units as stored in the file (None where the format stores none).

    ``source`` names the file in messages; ``first_row`` is the chunk's first row in it.
    """

    def __init__(self, columns: dict, units: dict, source: str, first_row: int = 0):
        self.columns = dict(columns)
        self.units = dict(units)
        self.source = source
        self.first_row = first_row

    @property
    def names(self) -> list[str]:
        return list(self.columns)

    def __len__(self) -> int:
        for v in self.columns.values():
            return len(v)
        return 0

    def __getitem__(self, name):
        return self.columns[name]

    def __contains__(self, name) -> bool:
        return name in self.columns

    def find(self, *names: str):
        """The file's name of the first of ``names`` it has, matched case-insensitively; else None."""
        low = {str(n).lower(): n for n in self.columns}
        for n in names:
            if str(n).lower() in low:
                return low[str(n).lower()]
        return None

    def unit(self, name):
        return self.units.get(name)

    def take(self, rows) -> "TableChunk":
        """The rows ``rows`` (indices or a boolean mask), in that order."""
        rows = np.flatnonzero(rows) if np.asarray(rows).dtype == bool else np.asarray(rows, dtype=np.int64)
        return TableChunk({k: (v.take(rows) if isinstance(v, Ragged) else v[rows]) for k, v in self.columns.items()},
                          self.units, self.source, self.first_row + (int(rows[0]) if rows.size else 0))

    @staticmethod
    def concat(chunks: list["TableChunk"]) -> "TableChunk":
        """The rows of ``chunks`` one after the other (same columns)."""
        chunks = [c for c in chunks if c is not None]
        if len(chunks) == 1:
            return chunks[0]
        cols = {}
        for name in chunks[0].names:
            parts = [c[name] for c in chunks]
            if any(isinstance(p, Ragged) for p in parts) or len({np.shape(p)[1:] for p in parts}) > 1:
                rag = [as_ragged(p, name=name, source=chunks[0].source) for p in parts]
                cols[name] = Ragged(np.concatenate([r.values for r in rag]), np.concatenate([r.lengths for r in rag]))
            else:
                cols[name] = np.concatenate(parts)
        return TableChunk(cols, chunks[0].units, chunks[0].source, chunks[0].first_row)

    def frame(self):
        """The scalar columns as a pandas DataFrame (array columns as object columns of arrays)."""
        import pandas as pd

        data = {}
        for k, v in self.columns.items():
            if isinstance(v, Ragged):
                data[k] = [v.values[s:s + n] for s, n in zip(v.starts, v.lengths)]
            elif getattr(v, "ndim", 1) > 1:
                data[k] = list(v)
            else:
                data[k] = v
        df = pd.DataFrame(data)
        df.attrs["units"] = dict(self.units)
        return df


def _unreadable(path: Path, fmt: str, exc: BaseException, what: str) -> UserInputError:
    label = f"{what} {path.name}".strip()
    return UserInputError(f"{label}: cannot be read as {fmt} ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0][:160] if str(exc) else ''}); expected a {fmt} table")


def _check_file(path: Path, what: str) -> None:
    if not path.is_file():
        label = f"{what} {path}".strip()
        raise UserInputError(f"{label} does not exist; expected a readable table file")


def _arrow_column(col) -> object:
    """A pyarrow column as numpy: lists as 2-D (equal lengths, no nulls) or ``Ragged``."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if isinstance(col, pa.ChunkedArray):
        col = col.combine_chunks()
    if pa.types.is_list(col.type) or pa.types.is_large_list(col.type) or pa.types.is_fixed_size_list(col.type):
        lengths = pc.fill_null(pc.list_value_length(col), 0).to_numpy(zero_copy_only=False).astype(np.int64)
        flat = pc.list_flatten(col)
        values = _arrow_scalar(flat)
        if lengths.size and (lengths == lengths[0]).all() and lengths[0] > 0 and values.size == lengths.sum():
            return values.reshape(lengths.size, int(lengths[0]))
        return Ragged(values, lengths)
    return _arrow_scalar(col)


def _arrow_scalar(col) -> np.ndarray:
    import pyarrow as pa

    if col.null_count and (pa.types.is_floating(col.type) or pa.types.is_integer(col.type)):
        if pa.types.is_integer(col.type):
            # NaN for the nulls; an unsafe cast, as integers beyond 2**53 (nanosecond times)
            # round to float64's 53 bits (32 ns at 1.7e17 ns) instead of raising.
            return col.cast(pa.float64(), safe=False).to_numpy(zero_copy_only=False)
        return col.to_numpy(zero_copy_only=False)
    if pa.types.is_boolean(col.type) and col.null_count:
        return col.fill_null(False).to_numpy(zero_copy_only=False)
    return col.to_numpy(zero_copy_only=False)


def _astropy_column(col) -> object:
    """An astropy Table column as numpy (masked floats NaN; variable-length arrays ``Ragged``)."""
    if col.dtype.kind == "O":
        cells = list(col)
        if cells and all(isinstance(c, np.ndarray) for c in cells):
            # Variable-length arrays (FITS 'P' columns, VOTable arrays '*'): one value array.
            filled = [np.ma.filled(c, np.nan) if np.ma.isMaskedArray(c) and c.dtype.kind == "f"
                      else np.ma.getdata(c) for c in cells]
            lengths = np.fromiter((c.size for c in filled), dtype=np.int64, count=len(filled))
            values = np.concatenate(filled) if filled else np.empty(0)
            if np.ma.isMaskedArray(col) or any(np.ma.isMaskedArray(c) and np.ma.getmaskarray(c).any()
                                               for c in cells if c.dtype.kind != "f"):
                masks = np.concatenate([np.ma.getmaskarray(c) for c in cells]) if cells else np.empty(0, bool)
                if masks.any():
                    values = values.astype(float)
                    values[masks] = np.nan
            return Ragged(values, lengths)
        return np.asarray(col)
    data = col
    if hasattr(col, "mask") and np.any(col.mask):
        if col.dtype.kind == "f":
            return np.asarray(col.filled(np.nan))
        if col.dtype.kind in "iu":
            return np.asarray(col.astype(float).filled(np.nan))
        if col.dtype.kind == "b":
            return np.asarray(col.filled(False))
    return np.asarray(getattr(data, "data", data))


def _csv_kwargs(path: Path, header_names) -> dict:
    sep = "\t" if ".tsv" in path.name.lower() else ","
    dtype = {n: str for n in header_names if is_identifier(n)}
    return {"sep": sep, "comment": "#", "dtype": dtype or None, "compression": "infer"}


def _csv_header(path: Path, what: str):
    import pandas as pd

    try:
        return list(pd.read_csv(path, nrows=0, comment="#", sep="\t" if ".tsv" in path.name.lower() else ",",
                                compression="infer").columns)
    except Exception as exc:  # pandas raises many types; one line for the user
        raise _unreadable(path, "csv", exc, what) from None


def _chunk_of_frame(df, source: str, first_row: int) -> TableChunk:
    return TableChunk({str(c): df[c].to_numpy() for c in df.columns}, {str(c): None for c in df.columns},
                      source, first_row)


def astropy_table(path, fmt: str, what: str = ""):
    """The file as an astropy Table (FITS, VOTable, ECSV: units and descriptions kept); one-line error if unreadable."""
    path = Path(path)
    import warnings

    from astropy.table import Table

    try:
        with warnings.catch_warnings():
            # Units the archive writes that astropy does not know ('1/nm' variants): kept as text.
            warnings.simplefilter("ignore")
            return Table.read(path, format=ASTROPY_FORMAT[fmt])
    except Exception as exc:  # the readers raise many types; report them on one line
        raise _unreadable(path, fmt, exc, what) from None


def read_table(path, *, fmt: str = "auto", what: str = "") -> TableChunk:
    """Read the whole table in ``path``.

    Parameters
    ----------
    path : str or path-like
        A FITS, VOTable, ECSV, CSV or Parquet file.
    fmt : str, keyword-only
        'auto' (from the suffix), 'fits', 'votable', 'ecsv', 'csv' or 'parquet'.
    what : str, keyword-only
        The file's role, for messages (e.g. 'catalogue').

    Returns
    -------
    TableChunk
        The table's columns with their units.

    Raises
    ------
    mcsweep.errors.UserInputError
        One line, if the file is missing or unreadable in that format.

    Examples
    --------
    >>> from importlib.resources import files
    >>> data = files('mcsweep') / 'data' / 'epoch_astrometry'
    >>> from mcsweep.tables import read_table
    >>> t = read_table(data / 'sample_sources.csv', what='sources')
    >>> len(t), t.names[:3]
    (10, ['source_id', 'ra', 'dec'])
    """
    return TableChunk.concat(list(iter_tables(path, fmt=fmt, what=what, batch_rows=None)))


def iter_tables(path, *, fmt: str = "auto", what: str = "", batch_rows: int | None = DEFAULT_BATCH_ROWS,
                columns=None) -> Iterator[TableChunk]:
    """Read the table in ``path`` in batches.

    Parameters
    ----------
    path : str or path-like
        A FITS, VOTable, ECSV, CSV or Parquet file.
    fmt : str, keyword-only
        'auto' (from the suffix), 'fits', 'votable', 'ecsv', 'csv' or 'parquet'.
    what : str, keyword-only
        The file's role, for messages.
    batch_rows : int or None, keyword-only
        Rows per batch; None: all rows at once. Parquet and CSV are streamed; the other
        formats are read whole and then cut.
    columns : list of str, optional, keyword-only
        Read only these (the file's names), where the format allows it (Parquet, CSV).

    Yields
    ------
    TableChunk
        The next batch of rows.

    Examples
    --------
    >>> from importlib.resources import files
    >>> data = files('mcsweep') / 'data' / 'epoch_astrometry'
    >>> from mcsweep.tables import iter_tables
    >>> path = data / 'sample_epoch_astrometry.parquet'
    >>> [len(b) for b in iter_tables(path, batch_rows=400)]
    [400, 400, 180]
    """
    path = Path(path)
    fmt = detect_format(path, fmt, what=what)
    _check_file(path, what)
    source = path.name
    if fmt == "parquet":
        yield from _parquet_batches(path, batch_rows, columns, what)
    elif fmt == "csv":
        yield from csv_batches(path, batch_rows, columns, what)
    else:
        t = astropy_table(path, fmt, what)
        names = [n for n in t.colnames if columns is None or n in columns]
        cols = {n: _astropy_column(t[n]) for n in names}
        units = {n: (str(t[n].unit) if t[n].unit is not None else None) for n in names}
        n = len(t)
        step = n if not batch_rows else batch_rows
        for start in range(0, max(n, 1), max(step, 1)):
            stop = min(n, start + step)
            rows = np.arange(start, stop)
            yield TableChunk({k: (v.take(rows) if isinstance(v, Ragged) else v[start:stop]) for k, v in cols.items()},
                             units, source, start)


def arrow_batches(path, batch_rows: int | None, *, columns=None, what: str = ""):
    """(pyarrow schema, iterator of pyarrow RecordBatches) of a Parquet file, for callers that
    pass the file's own column types through (annotate); one-line error if unreadable."""
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        # pre_buffer=False: with pre-buffering pyarrow keeps read-ahead buffers of past row
        # groups and the peak memory grows with the file (276 MB at 1e6 rows, 413 MB at 4e6;
        # without it 276 MB for both, measured when annotate first streamed Parquet).
        pf = pq.ParquetFile(path, pre_buffer=False)
    except Exception as exc:  # pyarrow raises ArrowInvalid, OSError, ...
        raise _unreadable(path, "parquet", exc, what) from None
    size = batch_rows or max(pf.metadata.num_rows, 1)

    def batches():
        try:
            yield from pf.iter_batches(batch_size=size, columns=columns)
        except Exception as exc:  # a damaged row group: one line, as for the header
            raise _unreadable(path, "parquet", exc, what) from None

    return pf.schema_arrow, batches()


def parquet_rows(path, start: int, stop: int, *, columns=None, what: str = "") -> TableChunk:
    """Rows ``start`` to ``stop`` (exclusive) of a Parquet file, reading only the row groups
    that hold them (and only ``columns``, if given): a worker reads its own part of a file
    shared with others."""
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        pf = pq.ParquetFile(path, pre_buffer=False)
        sizes = np.array([pf.metadata.row_group(i).num_rows for i in range(pf.num_row_groups)], dtype=np.int64)
        ends = np.cumsum(sizes)
        first = int(np.searchsorted(ends, start, side="right"))
        last = int(np.searchsorted(ends, max(stop - 1, start), side="right"))
        table = pf.read_row_groups(list(range(first, last + 1)), columns=columns)
    except Exception as exc:  # pyarrow raises ArrowInvalid, OSError, ...
        raise _unreadable(path, "parquet", exc, what) from None
    offset = int(ends[first - 1]) if first else 0
    table = table.slice(start - offset, stop - start)
    units = {}
    for f in pf.schema_arrow:
        meta = f.metadata or {}
        units[f.name] = meta[b"unit"].decode() if b"unit" in meta else None
    cols = {name: _arrow_column(table.column(i)) for i, name in enumerate(table.schema.names)}
    return TableChunk(cols, {k: units.get(k) for k in cols}, path.name, start)


def _parquet_batches(path: Path, batch_rows, columns, what) -> Iterator[TableChunk]:
    schema, batches = arrow_batches(path, batch_rows, columns=columns, what=what)
    units = {}
    for f in schema:
        meta = f.metadata or {}
        units[f.name] = meta[b"unit"].decode() if b"unit" in meta else None
    first = 0
    for batch in batches:
        cols = {name: _arrow_column(batch.column(i)) for i, name in enumerate(batch.schema.names)}
        yield TableChunk(cols, {k: units.get(k) for k in cols}, path.name, first)
        first += batch.num_rows
    if first == 0:
        names = columns or schema.names
        yield TableChunk({k: np.empty(0) for k in names}, {k: units.get(k) for k in names}, path.name, 0)


def csv_batches(path, batch_rows, columns=None, what: str = "") -> Iterator[TableChunk]:
    """Batches of a CSV file (gzip allowed) read by pandas, identifier columns as exact text."""
    path = Path(path)
    import pandas as pd

    header = _csv_header(path, what)
    kwargs = _csv_kwargs(path, header)
    if columns is not None:
        kwargs["usecols"] = [c for c in header if c in columns]
    first = 0
    try:
        if batch_rows:
            reader = pd.read_csv(path, chunksize=batch_rows, **kwargs)
            for df in reader:
                yield _chunk_of_frame(df, path.name, first)
                first += len(df)
            if first == 0:
                yield _chunk_of_frame(pd.DataFrame(columns=header), path.name, 0)
        else:
            yield _chunk_of_frame(pd.read_csv(path, **kwargs), path.name, 0)
    except UserInputError:
        raise
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError, OSError,
            EOFError) as exc:
        raise _unreadable(path, "csv", exc, what) from None


def as_ragged(column, *, name: str = "", source: str = "") -> Ragged:
    """A per-row array column in any stored form as ``Ragged``.

    Accepts a 2-D array, a ``Ragged``, an object array of sequences (lists, tuples,
    arrays) or of strings such as ``"(1.5, 2.5)"``, ``"[1.5,2.5]"`` or ``"(true, false)"``
    (the Gaia archive's CSV and ECSV text forms). Text values 'true'/'false' become 1/0 and
    'null'/'' NaN. Raises :class:`~mcsweep.errors.UserInputError` naming the column if a value is neither.
    """
    if isinstance(column, Ragged):
        return column
    arr = np.asarray(column) if not isinstance(column, np.ndarray) else column
    if arr.ndim == 2:
        return Ragged(arr.reshape(-1), np.full(arr.shape[0], arr.shape[1], dtype=np.int64))
    if arr.size == 0:
        return Ragged(np.empty(0), np.zeros(0, dtype=np.int64))
    if arr.dtype.kind == "O" and any(isinstance(v, str) for v in arr[:64]):
        # Text arrays with empty cells (pandas reads an empty CSV cell as NaN): empty text.
        arr = np.where(_isna(arr), "", arr)
    if arr.dtype.kind in "US" or (arr.dtype.kind == "O" and isinstance(arr[0], str)):
        return _parse_text_arrays(arr.astype(str), name, source)
    if arr.dtype.kind == "O":
        cells = [np.asarray(c) for c in arr]
        lengths = np.fromiter((c.size for c in cells), dtype=np.int64, count=len(cells))
        return Ragged(np.concatenate(cells) if cells else np.empty(0), lengths)
    raise UserInputError(f"{source}: column {name} holds one value per row; expected an array per row "
                         "(one element per CCD)")


def _isna(values) -> np.ndarray:
    """Element-wise missing-value test of an object array (None and float NaN)."""
    import pandas as pd

    return pd.isna(values)


def _parse_text_arrays(text: np.ndarray, name: str, source: str) -> Ragged:
    import pandas as pd

    # '(1.5, 2.5)' (the archive's CSV), '[1.5,2.5]' (ECSV), '[1.5 2.5]' (numpy's text, as pandas
    # writes an array cell): commas or white space between the elements.
    s = pd.Series(text).str.strip().str.strip("()[]{}").str.replace(",", " ", regex=False).str.split()
    lengths = s.str.len().fillna(0).to_numpy(dtype=np.int64)
    flat = s[lengths > 0].explode().astype(str).str.lower()
    mapped = flat.replace({"true": "1", "false": "0", "t": "1", "f": "0"})
    mapped = mapped.where(~mapped.isin(("null", "", "none", "--", "nan")), None)
    try:
        values = pd.to_numeric(mapped, errors="raise")
    except (TypeError, ValueError):
        bad = mapped[pd.to_numeric(mapped, errors="coerce").isna() & mapped.notna()]
        raise UserInputError(f"{source}: column {name} has the array element {bad.iloc[0] if len(bad) else '?'!r}; "
                             "expected numbers or true/false in each row's array") from None
    return Ragged(values.to_numpy(), lengths)
