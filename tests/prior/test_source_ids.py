"""mcsweep-prior solve keeps Gaia source_ids exact: ids beyond 2**53 are neither rounded nor merged."""

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

BIN = Path(sys.executable).parent
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "prior_solve"
#: Two real-size Gaia ids one apart: through float64 both become 4472832130942576128.
IDS = (4472832130942575873, 4472832130942575874)


def run(*args):
    return subprocess.run([str(BIN / "mcsweep-prior"), *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def two_sources(tmp_path, suffix):
    """The example's first two sources (4 and 3 transits are not needed: any two) renamed to IDS."""
    obs = pd.read_csv(EXAMPLE / "observations.csv")
    src = pd.read_csv(EXAMPLE / "sources.csv")
    first = sorted(obs["source_id"].unique())[:2]
    rename = dict(zip(first, IDS))
    obs = obs[obs["source_id"].isin(first)].assign(source_id=lambda d: d["source_id"].map(rename))
    src = src[src["source_id"].isin(first)].assign(source_id=lambda d: d["source_id"].map(rename))
    paths = tmp_path / f"obs{suffix}", tmp_path / f"src{suffix}"
    for table, path in zip((obs, src), paths):
        if suffix.startswith(".csv"):
            table.to_csv(path, index=False)
        else:
            table.to_parquet(path, index=False)
    return paths, obs.groupby("source_id").size()


@pytest.mark.parametrize("suffix", [".csv", ".csv.gz", ".parquet"])
def test_real_gaia_ids_are_not_merged(tmp_path, suffix):
    (obs_path, src_path), counts = two_sources(tmp_path, suffix)
    out = tmp_path / "sol.parquet"
    r = run("solve", obs_path, "--sources", src_path, "--out", out)
    assert r.returncode == 0, r.stderr
    got = pd.read_parquet(out)
    assert got["source_id"].dtype == "int64"
    assert list(got["source_id"]) == list(IDS)
    assert list(got["n_transits"]) == [counts[i] for i in IDS]


def test_an_id_that_is_not_an_exact_integer_is_refused(tmp_path):
    (obs_path, src_path), _ = two_sources(tmp_path, ".csv")
    obs = pd.read_csv(obs_path, dtype={"source_id": str})
    obs.loc[0, "source_id"] = "4.472832130942576e+18"
    obs.to_csv(obs_path, index=False)
    out = tmp_path / "sol.csv"
    r = run("solve", obs_path, "--sources", src_path, "--out", out)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1
    assert "source_id" in r.stderr and "4.472832130942576e+18" in r.stderr
    assert not out.exists()
