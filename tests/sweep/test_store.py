"""Cell files: atomic, verified, and never mistaken for finished when damaged or foreign."""

import pandas as pd
import pytest

import os

from mcsweep.sweep.store import CellStore, atomic_write_bytes, current_umask


def _table():
    return pd.DataFrame({"sigma_prior_mas": [0.01, 0.1, 1.0], "fraction_inside": [0.1, 0.5, 0.93], "case": "two"})


def test_roundtrip(tmp_path):
    store = CellStore(tmp_path, "abc")
    store.write("cell_1", _table())
    pd.testing.assert_frame_equal(store.read("cell_1"), _table())
    assert not list(tmp_path.glob(".*tmp"))  # no temporary files left behind


@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty"])
def test_damaged_file_is_recomputed_with_warning(tmp_path, damage):
    store = CellStore(tmp_path, "abc")
    path = store.write("cell_1", _table())
    data = path.read_bytes()
    path.write_bytes({"truncate": data[: len(data) // 2], "garbage": b"not parquet at all", "empty": b""}[damage])
    with pytest.warns(UserWarning, match="recomputing"):
        assert store.read("cell_1") is None


def test_foreign_and_other_config_files_are_not_taken(tmp_path):
    CellStore(tmp_path, "other").write("cell_1", _table())
    with pytest.warns(UserWarning, match="different config"):
        assert CellStore(tmp_path, "abc").read("cell_1") is None
    store = CellStore(tmp_path, "abc")
    store.write("cell_2", _table())
    (tmp_path / "cell_3.parquet").write_bytes((tmp_path / "cell_2.parquet").read_bytes())
    with pytest.warns(UserWarning, match="belongs to cell"):
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
