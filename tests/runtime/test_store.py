"""Cell files: atomic, verified, and never mistaken for finished when damaged or foreign."""

import io
import json
import os
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from mcsweep.runtime.store import (ResultStore, arrow_checksum, atomic_write_bytes, concat_parquet, current_umask,
                                   table_checksum, table_from_columns)


def _table():
    return pd.DataFrame({"sigma_prior_mas": [0.01, 0.1, 1.0], "fraction_inside": [0.1, 0.5, 0.93], "case": "two"})


def test_roundtrip(tmp_path):
    store = ResultStore(tmp_path, "abc")
    store.write("cell_1", _table())
    pd.testing.assert_frame_equal(store.read("cell_1"), _table())
    assert not list(tmp_path.glob(".*tmp"))  # no temporary files left behind


@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty"])
def test_damaged_file_is_recomputed_with_warning(tmp_path, damage):
    store = ResultStore(tmp_path, "abc")
    store.write("cell_1", _table())
    path = store.path("cell_1")
    data = path.read_bytes()
    path.write_bytes({"truncate": data[: len(data) // 2], "garbage": b"not parquet at all", "empty": b""}[damage])
    with pytest.warns(UserWarning, match="recomputing"):
        assert store.read("cell_1") is None


def test_foreign_and_other_config_files_are_not_taken(tmp_path):
    ResultStore(tmp_path, "other").write("cell_1", _table())
    with pytest.warns(UserWarning, match="different config"):
        assert ResultStore(tmp_path, "abc").read("cell_1") is None
    store = ResultStore(tmp_path, "abc")
    store.write("cell_2", _table())
    (tmp_path / "cell_3.parquet").write_bytes((tmp_path / "cell_2.parquet").read_bytes())
    with pytest.warns(UserWarning, match="belongs to entry"):
        assert store.read("cell_3") is None
    _table().to_parquet(tmp_path / "cell_4.parquet")  # a plain Parquet file without our metadata
    with pytest.warns(UserWarning, match="unreadable"):
        assert store.read("cell_4") is None


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o027, 0o640), (0o077, 0o600)])
def test_atomic_write_gives_the_mode_of_a_normally_created_file(tmp_path, mask, mode):
    old = os.umask(mask)
    try:
        assert current_umask() == mask
        atomic_write_bytes(tmp_path / "sub" / "f.csv", b"a,b\n")
        with open(tmp_path / "plain.csv", "w") as f:  # what the OS gives a file created normally
            f.write("a,b\n")
    finally:
        os.umask(old)
    assert (tmp_path / "sub" / "f.csv").stat().st_mode & 0o777 == mode
    assert (tmp_path / "plain.csv").stat().st_mode & 0o777 == mode


def test_a_write_stopped_by_a_full_disk_leaves_nothing_and_names_the_file(tmp_path, monkeypatch):
    import errno
    from pathlib import Path

    store = ResultStore(tmp_path, "h1")
    store.write("c1", pd.DataFrame({"a": [1.0, 2.0]}))
    real_write_bytes = Path.write_bytes

    def half_then_full(self, data):  # a real write(): part of the bytes land, then ENOSPC without a name
        real_write_bytes(self, data[: len(data) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Path, "write_bytes", half_then_full)
    with pytest.raises(OSError) as info:
        store.write("c2", pd.DataFrame({"a": [3.0]}))
    monkeypatch.undo()
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / "c2.parquet")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c1.parquet"]  # the temporary went with the error
    assert store.finished() == ["c1"] and store.read("c2") is None


def test_finished_counts_only_whole_results_of_this_config(tmp_path):
    store = ResultStore(tmp_path, "h1")
    for cid in ("c1", "c2", "c3"):
        store.write(cid, pd.DataFrame({"a": [1.0]}))
    (tmp_path / "c2.parquet").write_bytes((tmp_path / "c2.parquet").read_bytes()[:-20])  # truncated
    ResultStore(tmp_path, "other").write("c4", pd.DataFrame({"a": [1.0]}))
    (tmp_path / ".c5.parquet.x1.tmp").write_bytes((tmp_path / "c1.parquet").read_bytes())  # a killed write's temporary
    assert ResultStore(tmp_path, "h1", version="a later version").finished() == ["c1", "c3"]


#: Writes OUT atomically and stops mid-write: the temporary's name goes to READY, then it sleeps.
_WRITER = """
import sys, time
from pathlib import Path
from mcsweep.runtime.store import atomic_write_via
out, ready = Path(sys.argv[1]), Path(sys.argv[2])
def write(tmp):
    tmp.write_bytes(b"partial")
    ready.write_text(str(tmp))
    time.sleep(600)
atomic_write_via(out, write)
"""


def _writer_mid_write(out, tmp_path):
    """(the process, its temporary) once it is inside ``write``."""
    import subprocess
    import sys
    import time

    ready = tmp_path / f"ready-{out.name}-{time.monotonic_ns()}"
    proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(out), str(ready)])
    deadline = time.monotonic() + 120
    while not ready.exists() or not ready.read_text():
        assert proc.poll() is None and time.monotonic() < deadline, "the writer did not start its write"
        time.sleep(0.02)
    return proc, Path(ready.read_text())


def _killed_mid_write(out, tmp_path):
    import signal

    proc, tmp = _writer_mid_write(out, tmp_path)
    proc.send_signal(signal.SIGKILL)
    assert proc.wait(timeout=60) == -signal.SIGKILL
    assert tmp.exists()  # what a SIGKILLed write leaves: no handler of its own ran
    return tmp


def test_a_write_removes_what_a_killed_write_of_the_same_output_left(tmp_path):
    import signal

    d = tmp_path / "out"
    d.mkdir()
    stale = _killed_mid_write(d / "cat.csv", tmp_path)
    other = _killed_mid_write(d / "other.csv", tmp_path)
    longer = _killed_mid_write(d / "cat.csv.gz", tmp_path)  # its name starts with the output's
    live, held = _writer_mid_write(d / "cat.csv", tmp_path)
    try:
        atomic_write_bytes(d / "cat.csv", b"whole")
        assert (d / "cat.csv").read_bytes() == b"whole"
        assert not stale.exists()
        assert other.exists() and longer.exists()  # another output's temporaries are not its own
        assert held.exists() and held.read_bytes() == b"partial"  # a live write's is left alone
    finally:
        live.send_signal(signal.SIGKILL)
        live.wait(timeout=60)
    # Once its writer is dead the kernel has released its lock: the next write takes it.
    atomic_write_bytes(d / "cat.csv", b"again")
    assert not held.exists() and other.exists() and longer.exists()
    assert sorted(p.name for p in d.iterdir()) == sorted([longer.name, other.name, "cat.csv"])


def test_a_cell_store_clears_only_unheld_temporaries(tmp_path):
    import signal

    d = tmp_path / "cells"
    proc, held = _writer_mid_write(d / "c1.parquet", tmp_path)
    try:
        stale = d / ".c2.parquet.abc123.tmp"  # no process holds it: a killed write's
        stale.write_bytes(b"partial")
        assert ResultStore(d, "h1").remove_stale_temporaries() == 1
        assert not stale.exists() and held.exists()
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)


def test_decoded_bytes_are_what_read_gives(tmp_path):
    store = ResultStore(tmp_path, "abc")
    data = store.write("cell_1", _table())
    assert store.decode(data).equals(store.read_table("cell_1"))
    pd.testing.assert_frame_equal(pd.read_parquet(io.BytesIO(concat_parquet([store.decode(data)]))),
                                  store.read("cell_1"), check_exact=True)


def test_concatenated_tables_are_the_concatenated_frames(tmp_path):
    store = ResultStore(tmp_path, "abc")
    frames = [_table().assign(cell=f"c{i}", x=float(i)) for i in range(3)]
    tables = [store.decode(store.write(f"c{i}", df)) for i, df in enumerate(frames[:2])]
    store.write("c2", frames[2])
    tables.append(store.read_table("c2"))
    pd.testing.assert_frame_equal(pd.read_parquet(io.BytesIO(concat_parquet(tables))),
                                  pd.concat(frames, ignore_index=True), check_exact=True)


def _awkward_frame():
    """Columns whose Arrow form a Parquet round trip may change: a categorical (its
    dictionary's string width), NaN and None (nulls, and what lies under them), nullable
    integers and booleans."""
    n = 12
    return pd.DataFrame({
        "x": [float(i) if i % 3 else float("nan") for i in range(n)],
        "label": [None if i % 4 == 0 else f"v{i}" for i in range(n)],
        "population": pd.Categorical(["thin_disc", "halo"] * (n // 2), categories=["thin_disc", "halo", "bulge"]),
        "count": pd.array([i if i % 5 else None for i in range(n)], dtype="Int64"),
        "flag": pd.array([True, None, False] * (n // 3), dtype="boolean"),
        "all_nan": [float("nan")] * n,
    })


def test_checksum_of_a_table_is_the_checksum_of_its_file(tmp_path):
    table = pa.Table.from_pandas(_awkward_frame(), preserve_index=False)
    pq.write_table(table, tmp_path / "t.parquet")
    assert arrow_checksum(pq.read_table(tmp_path / "t.parquet")) == arrow_checksum(table)
    store = ResultStore(tmp_path, "abc")
    store.write("frame", _awkward_frame())
    store.write("slice", table.slice(3, 6))  # a slice's offsets are not its values
    pd.testing.assert_frame_equal(store.read("frame"), _awkward_frame())
    pd.testing.assert_frame_equal(store.read("slice"), table.slice(3, 6).to_pandas())


@pytest.mark.parametrize("change", ["value", "null", "order"])
def test_a_changed_table_does_not_pass_for_the_written_one(tmp_path, change):
    store = ResultStore(tmp_path, "abc")
    store.write("cell_1", _awkward_frame())
    table = pq.read_table(store.path("cell_1"))
    x = table.column("x").to_pylist()
    x = {"value": [x[0]] + [x[1] + 1e-12] + x[2:], "null": [x[0], None] + x[2:], "order": x[::-1]}[change]
    changed = table.set_column(0, "x", pa.array(x, pa.float64())).replace_schema_metadata(table.schema.metadata)
    pq.write_table(changed, store.path("cell_1"))
    with pytest.warns(UserWarning, match="checksum does not match"):
        assert store.read("cell_1") is None


def test_files_of_the_former_pandas_checksum_are_still_verified(tmp_path):
    # Files written before arrow_checksum carry table_checksum's value and no "checksum_of":
    # a resumed run keeps them, and still refuses a damaged one.
    df = _table()
    meta = {"config_hash": "abc", "cell_id": "cell_1", "checksum": table_checksum(df), "n_rows": len(df),
            "code_version": ResultStore(tmp_path, "abc").version}
    table = pa.Table.from_pandas(df, preserve_index=False)
    pq.write_table(table.replace_schema_metadata({**table.schema.metadata, b"mcsweep": json.dumps(meta).encode()}),
                   tmp_path / "cell_1.parquet")
    pd.testing.assert_frame_equal(ResultStore(tmp_path, "abc").read("cell_1"), df)
    meta["checksum"] = table_checksum(df.assign(fraction_inside=0.5))
    pq.write_table(table.replace_schema_metadata({**table.schema.metadata, b"mcsweep": json.dumps(meta).encode()}),
                   tmp_path / "cell_1.parquet")
    with pytest.warns(UserWarning, match="checksum does not match"):
        assert ResultStore(tmp_path, "abc").read("cell_1") is None


def test_tables_from_columns_are_what_pandas_makes_of_them():
    # The schema pandas gave one kind of table is reused only for tables of the same kinds of
    # columns: an int scalar where a float was, or a None among strings, is converted anew
    # (pandas would give them other Arrow types).
    import numpy as np

    def columns(scalar, flag):
        return {"x": np.arange(3.0), "n": np.full(3, scalar), "flag": np.array([flag, "ok", "ok"], dtype=object)}

    for cols in (columns(1.5, "ok"), columns(2, "ok"), columns(np.nan, None), columns(1.5, "ok"), columns(3, "a")):
        assert table_from_columns(cols).equals(pa.Table.from_pandas(pd.DataFrame(cols), preserve_index=False),
                                               check_metadata=True)
