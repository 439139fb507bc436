"""The one table reader: formats, batches, text arrays, exact identifiers, the archive CSV's header."""

import gzip
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mcsweep.astrometry.epoch_astrometry import ccd_observations, fix_archive_header
from mcsweep.errors import UserInputError
from mcsweep.tables import as_ragged, integer_ids, iter_tables, read_table

DATALINK = Path(__file__).resolve().parents[1] / "data" / "gaiasupdate" / "gacs_data_link"
CSV = DATALINK / "EPOCH_ASTROMETRY-Gaia DR4_INT2 1.csv"


@pytest.mark.parametrize("suffix", ["csv", "ecsv", "fits", "votplain.xml"])
def test_every_datalink_product_reads_to_the_same_arrays(suffix):
    ref = read_table(DATALINK / "EPOCH_ASTROMETRY-Gaia DR4_INT2 1.xml")
    t = read_table(DATALINK / f"EPOCH_ASTROMETRY-Gaia DR4_INT2 1.{suffix}")
    assert len(t) == len(ref) == 79
    for ours, camel in (("centroid_pos_al", "centroidPosAl"), ("scan_pos_angle", "scanPosAngle"),
                        ("used_by_agis_al", "usedByAgisAl")):
        a = as_ragged(t[t.find(ours)]).values.astype(float)
        b = as_ragged(ref[ours]).values.astype(float)
        assert np.array_equal(np.isnan(a), np.isnan(b))
        # the text forms hold float32 values printed in ~8 digits
        assert np.allclose(a[~np.isnan(a)], b[~np.isnan(b)], rtol=1e-6, atol=1e-9)


def test_gzipped_csv_reads_like_csv(tmp_path):
    gz = tmp_path / "epochs.csv.gz"
    with open(CSV, "rb") as f, gzip.open(gz, "wb") as g:
        shutil.copyfileobj(f, g)
    a, b = read_table(CSV), read_table(gz)
    assert a.names == b.names
    for n in a.names:
        assert np.array_equal(a[n], b[n], equal_nan=a[n].dtype.kind == "f"), n


def test_parquet_batches_are_row_groups_of_the_whole(tmp_path):
    df = pd.read_parquet(DATALINK / "1_epoch_astrometry.parquet")
    path = tmp_path / "t.parquet"
    df.to_parquet(path, row_group_size=10, index=False)
    parts = list(iter_tables(path, batch_rows=10))
    assert [len(p) for p in parts] == [10] * 7 + [9]
    whole = read_table(path)
    assert np.array_equal(np.concatenate([p["sourceId"] for p in parts]), whole["sourceId"])


def test_text_arrays_lists_and_booleans():
    r = as_ragged(np.array(["(1.5, 2.5, null)", "[3,4]", "(true, false)", ""], dtype=object), name="c")
    assert list(r.lengths) == [3, 2, 2, 0]
    assert np.array_equal(r.values, [1.5, 2.5, np.nan, 3, 4, 1, 0], equal_nan=True)
    with pytest.raises(UserInputError, match="array element 'x'"):
        as_ragged(np.array(["(1, x)"], dtype=object), name="c", source="f.csv")


def test_identifiers_beyond_float64_stay_exact(tmp_path):
    ids = [4472832130942575873, 4472832130942575874]
    path = tmp_path / "s.csv"
    path.write_text("source_id,ra\n" + "".join(f"{i},1.0\n" for i in ids))
    assert list(integer_ids(read_table(path)["source_id"], "source_id", "s.csv")) == ids
    with pytest.raises(UserInputError, match="not an exact integer"):
        integer_ids(np.array(ids, dtype=float), "source_id", "s.csv")
    assert list(integer_ids(np.array(["12", "12.0", "-3"]), "source_id", "s.csv")) == [12, 12, -3]


def test_archive_csv_repeated_used_by_agis_al_header():
    t = read_table(CSV)
    assert "used_by_agis_al.1" in t.names
    fix_archive_header(t)
    # In the archive's CSV the second column repeats the AL flags: no AC flags are made up from it.
    assert "used_by_agis_al.1" not in t.names and t.find("used_by_agis_ac") is None
    t2 = read_table(CSV)
    t2.columns["used_by_agis_al.1"] = np.array(["(false)"] * len(t2), dtype=object)
    fix_archive_header(t2)
    assert t2.find("used_by_agis_ac") == "used_by_agis_ac"
    # The AL flags, and so the observations kept, are those of the first column.
    assert len(ccd_observations(read_table(CSV))) == len(ccd_observations(read_table(DATALINK /
                                                                                     "1_epoch_astrometry.parquet")))


def test_unreadable_and_unknown_files_are_one_line(tmp_path):
    bad = tmp_path / "x.parquet"
    bad.write_text("not parquet")
    with pytest.raises(UserInputError, match="cannot be read as parquet"):
        read_table(bad)
    with pytest.raises(UserInputError, match="cannot tell the format"):
        read_table(tmp_path / "x.dat")
    with pytest.raises(UserInputError, match="does not exist"):
        read_table(tmp_path / "missing.csv")
