"""Results on disk, one entry per file: atomic Parquet files that prove they are complete.

An entry is what one task computes: a sweep's cell, a global experiment's chunk of stars,
a primary solution's part of its per-star results. Its file is written to a temporary name in the same directory, flushed and
renamed over the final name (``os.replace`` is atomic on POSIX), so a killed worker
leaves either no file or a whole one, and at most a temporary, which the next write of
the same file removes (:func:`atomic_write_via`: the writer's ``flock`` on it tells a
live write's from a killed one's). A file counts as finished only if it parses as
Parquet, carries this run's config hash and the entry's identity in its metadata, and
its table checksum (:func:`arrow_checksum`) matches; anything else (truncated, foreign,
from another config) is recomputed with a warning.

Each file also records the code version that wrote it (:func:`mcsweep.runtime.version.code_version`).
A finished entry of another version is refused with one line naming both versions
(:class:`~mcsweep.errors.UserInputError`), unless the store was opened with
``accept_other_versions=True`` (the user's ``resume.accept_other_versions=true``): a
resumed run after an upgrade must not mix results of two codes silently.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import stat
import tempfile
import warnings
from collections import Counter
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import UserInputError
from .version import code_version

__all__ = ["ResultStore", "concat_parquet", "atomic_write_bytes", "atomic_write_via", "current_umask",
           "remove_temporaries", "table_checksum", "arrow_checksum", "table_from_columns"]

_META_KEY = b"mcsweep"


#: Metadata ``checksum_of`` of a file whose checksum is :func:`arrow_checksum`'s; files without
#: it (written before) carry :func:`table_checksum`'s and are verified with it.
_ARROW_CHECKSUM = "arrow"


def arrow_checksum(table: pa.Table) -> str:
    """SHA-256 over an Arrow table's column names, types and values, row order included.

    Taken over the uncompressed Arrow IPC stream of a canonical copy: per column its null
    flags and its values with nulls set to zero, dictionaries decoded, strings as large
    strings, in one record batch, without metadata. A Parquet round trip keeps these (it may
    change a dictionary's string width and what lies under a null), so the value of a table
    when written is the value of the table read back. Computed without pandas, so a task that
    builds its result as Arrow never makes a DataFrame. The schema's metadata (pandas' dtypes
    and categories) is not covered: the checksum proves the values whole. Should a future
    pyarrow encode IPC differently, a resumed run recomputes its entries (it never takes
    one unverified).
    """
    names, arrays = [], []
    for name, column in zip(table.column_names, table.columns):
        arr = column.combine_chunks()
        if pa.types.is_dictionary(arr.type):
            arr = arr.dictionary_decode()
        if pa.types.is_string(arr.type) or pa.types.is_large_string(arr.type) or _is_string_view(arr.type):
            arr = arr.cast(pa.large_string())
        names += [name, name + "\0null"]
        arrays += [_nulls_as_zero(arr), arr.is_null()]
    plain = pa.Table.from_arrays(arrays, names=names)
    sink = pa.BufferOutputStream()
    with pa.ipc.new_stream(sink, plain.schema) as writer:
        writer.write_table(plain, max_chunksize=max(plain.num_rows, 1))
    return hashlib.sha256(sink.getvalue()).hexdigest()


def _is_string_view(t) -> bool:
    is_view = getattr(pa.types, "is_string_view", None)  # pyarrow >= 16
    return bool(is_view and is_view(t))


def _nulls_as_zero(arr: pa.Array) -> pa.Array:
    if not arr.null_count:
        return arr
    import pyarrow.compute as pc

    t = arr.type
    if pa.types.is_large_string(t):
        zero = pa.scalar("", t)
    elif pa.types.is_boolean(t):
        zero = pa.scalar(False)
    elif pa.types.is_null(t):
        return arr
    else:
        try:
            zero = pa.scalar(0).cast(t)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            zero = None
    try:
        return arr if zero is None else pc.fill_null(arr, zero)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        # no zero of this type: the nulls stay, and a file whose round trip changes what lies
        # under them is recomputed (never taken unverified)
        return arr


#: The Arrow schema pandas gave a table, per kind of columns (:func:`_column_kinds`), in this
#: process (types and pandas metadata as pandas makes them).
_SCHEMAS: dict[tuple, pa.Schema] = {}


def _column_kinds(columns: dict) -> tuple:
    """What pandas' conversion of the columns depends on: their names, numpy types and, for
    object columns, the Python types of their values (str, or None among them)."""
    return tuple((name, v.dtype.str, frozenset(map(type, v)) if v.dtype == object else None)
                 for name, v in columns.items())


def table_from_columns(columns: dict) -> pa.Table:
    """``pa.Table.from_pandas(pd.DataFrame(columns), preserve_index=False)`` without the
    DataFrame, for many tables of the same kinds of columns (``columns``: name -> 1-d numpy
    array): the schema pandas gives the first is reused (a sweep cell's DataFrame and its
    conversion cost more than the cell's arithmetic of the prior grid); a table of other
    kinds is converted by pandas."""
    kinds = _column_kinds(columns)
    schema = _SCHEMAS.get(kinds)
    if schema is None:
        table = pa.Table.from_pandas(pd.DataFrame(columns), preserve_index=False)
        _SCHEMAS[kinds] = table.schema
        return table
    return pa.Table.from_arrays([pa.array(columns[f.name], type=f.type, from_pandas=True) for f in schema],
                                schema=schema)


def table_checksum(df: pd.DataFrame) -> str:
    """SHA-256 over the table's values (row order and column names included): the checksum
    of files written before :func:`arrow_checksum` (metadata without ``checksum_of``)."""
    h = hashlib.sha256()
    h.update(json.dumps(list(map(str, df.columns))).encode())
    h.update(pd.util.hash_pandas_object(df, index=False).values.tobytes())
    return h.hexdigest()


def current_umask() -> int:
    """The process's file-creation mask, read without changing it where the OS allows."""
    try:
        # Linux >= 4.7 reports it; setting and restoring os.umask would briefly leave a
        # mask of 0 for every other thread of the process.
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _held_temporary(path: Path) -> tuple[int, str]:
    """A new temporary for ``path`` (``.NAME.XXXX.tmp`` beside it) and an open descriptor
    holding an exclusive ``flock`` on it, kept until the write ends.

    The lock is what tells a live write from a killed one (:func:`remove_temporaries`):
    the kernel drops it when the process ends, SIGKILL included, and it belongs to this
    open file, so ``write`` opening and closing the name does not release it (flock(2);
    on NFS, where Linux emulates flock with POSIX record locks, that close does release
    it, so there two processes writing the same output at once could take each other's
    temporary for a killed write's). A process id in the name could not tell so safely:
    a dead writer's id may be a live process's by now, and a writer on another host
    sharing the file system has an id that means nothing here.
    """
    while True:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            # Between mkstemp and the lock a clean-up may have taken the unheld file for a
            # killed write's and removed it: then the name is no longer this file.
            if os.path.samestat(os.fstat(fd), os.stat(tmp)):
                return fd, tmp
        except FileNotFoundError:
            pass
        except BaseException:
            os.close(fd)
            Path(tmp).unlink(missing_ok=True)
            raise
        os.close(fd)


def atomic_write_via(path: Path, write) -> None:
    """Call ``write(tmp_path)`` and move the finished file to ``path`` in one step.

    Readers see either the old file or the whole new one, and an error (in ``write``
    or after it) leaves no file behind. The file gets the mode of a file created
    normally (``0o666 & ~umask``: 0644 under the usual 022), not the 0600 of its
    private temporary name, so colleagues sharing the run directory on a cluster file
    system can read it; it is flushed to disk before it replaces ``path``.

    A process killed during ``write`` (SIGKILL, the out-of-memory killer) cannot remove
    its temporary; this write first removes those a killed write of the same ``path``
    left (``remove_temporaries(path.parent, of=path.name)``: one listing of the
    directory), never one a live write holds.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_temporaries(path.parent, of=path.name)
    lock_fd, tmp = _held_temporary(path)
    try:
        os.fchmod(lock_fd, 0o666 & ~current_umask())
        write(Path(tmp))
        # A writer may have replaced the file (then it has the normal mode already).
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        if exc.filename in (None, tmp):
            # A failed write() or fsync() names no file, and the temporary name means
            # nothing to the user: the message (a full disk) must say which file it was.
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        os.close(lock_fd)


def _is_temporary(name: str, of: str | None) -> bool:
    """Whether ``name`` is a temporary of :func:`atomic_write_via`; with ``of``, one of the
    output named so only: ``.OF.XXXX.tmp`` with no dot in XXXX (mkstemp's random part has
    none), so ``.a.csv.gz.XXXX.tmp`` of the output ``a.csv.gz`` is not one of ``a.csv``."""
    if of is None:
        return name.startswith(".") and name.endswith(".tmp")
    prefix = f".{of}."
    middle = name[len(prefix):-len(".tmp")]
    return name.startswith(prefix) and name.endswith(".tmp") and bool(middle) and "." not in middle


def _remove_if_unheld(p: Path) -> bool:
    """Delete the temporary ``p`` unless a live write holds its lock (:func:`_held_temporary`)."""
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:  # gone meanwhile, a symbolic link, or not ours to read
        return False
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return False
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # held: its writer is alive
            return False
        # Deleted while held, and only if the name is still this file: a writer that has
        # just created it and not yet locked it finds its name gone and makes another.
        try:
            if not os.path.samestat(os.fstat(fd), os.stat(p)):
                return False
        except FileNotFoundError:
            return False
        p.unlink(missing_ok=True)
        return True
    finally:
        os.close(fd)


def remove_temporaries(directory, *, recursive: bool = False, of: str | None = None) -> int:
    """Delete the temporaries of :func:`atomic_write_via` (``.NAME.XXXX.tmp``) in ``directory``
    (and below it with ``recursive``) that no live write holds; their number. With ``of``,
    only those of the output of that name. A killed writer never removes its own, and they
    are never valid results; a live writer's lock keeps its own (:func:`_held_temporary`)."""
    directory = Path(directory)
    if not directory.is_dir():
        return 0
    if recursive:
        found = directory.rglob(".*.tmp")
    else:
        with os.scandir(directory) as entries:
            found = [Path(e.path) for e in entries if _is_temporary(e.name, of)]
    return sum(_remove_if_unheld(p) for p in found if _is_temporary(p.name, of))


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (:func:`atomic_write_via`)."""
    atomic_write_via(path, lambda tmp: tmp.write_bytes(data))


#: Entries per row group of :func:`concat_parquet`: about 27 000 rows of the sweep's cells.
CONCAT_GROUP = 128


def concat_parquet(tables) -> bytes:
    """One Parquet file of the Arrow tables of many entries (:meth:`ResultStore.read_table`,
    :meth:`ResultStore.decode`; any iterable, consumed once), in order, without their entry
    metadata: read with pandas it is ``pd.concat`` of their DataFrames. Written from Arrow,
    :data:`CONCAT_GROUP` entries per row group, so only one group's tables are held at a time
    (no DataFrame of them all is made on the way)."""
    sink = pa.BufferOutputStream()
    writer = None
    group: list = []

    def flush():
        nonlocal writer
        joined = pa.concat_tables(group)
        if writer is None:
            writer = pq.ParquetWriter(sink, joined.schema)
        writer.write_table(joined)
        group.clear()

    for t in tables:
        meta = {k: v for k, v in (t.schema.metadata or {}).items() if k != _META_KEY}
        group.append(t.replace_schema_metadata(meta))
        if len(group) == CONCAT_GROUP:
            flush()
    if group or writer is None:
        if not group:
            raise ValueError("concat_parquet: no tables")
        flush()
    writer.close()
    return sink.getvalue().to_pybytes()


class ResultStore:
    """Directory of one Parquet file per entry for one config (identified by its hash); an
    entry's id names its file (``<id>.parquet``) and is recorded in it (metadata ``cell_id``,
    the name it had when every entry was a sweep's cell, kept so older runs resume)."""

    def __init__(self, directory: Path, config_hash: str, *, version: str | None = None,
                 accept_other_versions: bool = False):
        self.directory = Path(directory)
        self.config_hash = config_hash
        self.version = version if version is not None else code_version()
        self.accept_other_versions = accept_other_versions
        #: Finished files read, per code version that wrote them.
        self.versions_read: Counter = Counter()

    def path(self, entry_id: str) -> Path:
        return self.directory / f"{entry_id}.parquet"

    def write(self, entry_id: str, data: pd.DataFrame | pa.Table) -> bytes:
        """Write the entry (a DataFrame, or the Arrow table ``pa.Table.from_pandas`` would make
        of one) atomically; returns the table as Arrow IPC bytes (:meth:`decode` gives it back
        without going to the disk, in microseconds rather than the milliseconds of reading
        Parquet)."""
        table = pa.Table.from_pandas(data, preserve_index=False) if isinstance(data, pd.DataFrame) else data
        meta = {"config_hash": self.config_hash, "cell_id": entry_id, "checksum": arrow_checksum(table),
                "checksum_of": _ARROW_CHECKSUM, "n_rows": table.num_rows, "code_version": self.version}
        table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                               _META_KEY: json.dumps(meta).encode()})
        sink = pa.BufferOutputStream()
        pq.write_table(table, sink)
        atomic_write_bytes(self.path(entry_id), sink.getvalue().to_pybytes())
        ipc = pa.BufferOutputStream()
        # LZ4: a third of the uncompressed bytes (the parent holds every cell's until the
        # aggregate; 12 kB per sweep cell, against 18 kB of Parquet), read back in 0.1 ms.
        with pa.ipc.new_stream(ipc, table.schema, options=pa.ipc.IpcWriteOptions(compression="lz4")) as writer:
            writer.write_table(table)
        return ipc.getvalue().to_pybytes()

    def decode(self, data: bytes) -> pa.Table:
        """The table of bytes :meth:`write` returned in this run, as :meth:`read_table` gives
        it from the file, without reading and checksumming it again (it was just written by
        this code)."""
        self.versions_read[self.version] += 1
        return pa.ipc.open_stream(pa.BufferReader(data)).read_all()

    def read(self, entry_id: str) -> pd.DataFrame | None:
        """The finished cell's table, or None (with a warning if a bad file was there)."""
        found = self._finished(entry_id)
        return None if found is None else found[1]

    def read_table(self, entry_id: str) -> pa.Table | None:
        """:meth:`read` as the Arrow table of the file (:func:`concat_parquet` joins many)."""
        found = self._finished(entry_id)
        return None if found is None else found[0]

    def _finished(self, entry_id: str):
        path = self.path(entry_id)
        if not path.exists():
            return None
        table, df, meta, problem = self._verified(entry_id)
        if problem:
            warnings.warn(f"recomputing {path.name}: {problem}", stacklevel=3)
            return None
        written_by = meta.get("code_version") or "an mcsweep too old to record its version"
        if written_by != self.version and not self.accept_other_versions:
            raise UserInputError(
                f"{self.directory.name}/{path.name} was computed by {written_by}, this is {self.version}; "
                "expected cells of one code version: resume with resume.accept_other_versions=true to keep "
                "them, or use a new hydra.run.dir")
        self.versions_read[written_by] += 1
        return table, df

    def finished(self) -> list[str]:
        """Ids of the whole results of this config (name order), whatever code version wrote them.

        Quiet and never raising: it tells a stopped command's user what is kept. The code
        version is left to :meth:`read`, which names both versions if a rerun meets cells of
        another (the checkout may change while a long run goes on). Temporaries of
        unfinished writes (``.*.tmp``) are never counted.
        """
        if not self.directory.is_dir():
            return []
        return [p.stem for p in sorted(self.directory.glob("*.parquet")) if self._verified(p.stem)[3] is None]

    def _verified(self, entry_id: str):
        """``(arrow table, table, metadata, problem)``; ``problem`` is None when the file is a
        finished result."""
        path = self.path(entry_id)
        table, df, meta = None, None, {}
        try:
            table = pq.read_table(path)
            meta = json.loads((table.schema.metadata or {})[_META_KEY])
            df = table.to_pandas()
            problem = None
            if meta.get("cell_id") != entry_id:
                problem = f"it belongs to entry {meta.get('cell_id')!r}"
            elif meta.get("config_hash") != self.config_hash:
                problem = "it was computed with a different config"
            elif meta.get("n_rows") != len(df) or meta.get("checksum") != (
                    arrow_checksum(table) if meta.get("checksum_of") == _ARROW_CHECKSUM else table_checksum(df)):
                problem = "its checksum does not match its content"
        except Exception as exc:  # truncated, not Parquet, no metadata
            problem = f"it is unreadable ({type(exc).__name__})"
        return table, df, meta, problem

    def remove_stale_temporaries(self) -> int:
        """Delete temporaries left by writes that were killed (never valid results)."""
        return remove_temporaries(self.directory)
