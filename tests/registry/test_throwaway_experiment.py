"""Adding an experiment is one folder, one registry entry and one YAML: a throwaway experiment
registered from the test suite runs through the command line like the built-in ones, and
registering it leaves every existing config hash as it was."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from omegaconf import OmegaConf

from mcsweep.command.provenance import config_hash
from mcsweep.command.validate import compose_config
from mcsweep.population.galaxy.model import PARAMS_R03_5

HERE = Path(__file__).resolve().parent
SEARCH = f"hydra.searchpath=[file://{HERE / 'throwaway' / 'conf'}]"
#: Config hashes computed by mcsweep at commit 66652ca, before experiments had a registry
#: (tests/sweep/test_ignored_settings.py holds the same values for the scanning-law refit).
HASHES_AT_66652CA = {
    (): "285a027a54185cfd",
    ("experiment=primary",): "13a87abc2770018d",
    ("experiment=real_sky",): "6163d0d02e11348f",
    ("observations=dr3",): "4ce02ffd0486d3fd",
    ("experiment=secondary", "experiment.secondary.mission_years=4.9"): "2e5afdc73d73e902",
    ("experiment=secondary", "observations=dr3"): "84a7d15abfd09dbb",
}
#: Configs of every built-in experiment with a setting of each section changed.
OTHER_CONFIGS = [("experiment=secondary",), ("experiment=primary", "experiment.primary.knot_transits=25"),
                 ("experiment=real_sky", "experiment.real_sky.factor=10"), ("confidence=0.8", "sky=single"),
                 ("experiment.showcase.g_min=13",)]


def _command(what: str, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "throwaway.command", what, *args], capture_output=True,
                          text=True, env=env, timeout=300)


def test_registering_an_experiment_leaves_every_existing_config_hash_unchanged():
    # the hashes at 66652ca were made under that day's galaxy model, besancon-r03-5
    r03_5 = [f"population.params.{k}={v}" for k, v in PARAMS_R03_5.items()]
    pinned = {" ".join(list(k) + r03_5): h for k, h in HASHES_AT_66652CA.items()}
    jobs = [list(k) + r03_5 for k in HASHES_AT_66652CA] + [list(k) for k in OTHER_CONFIGS]
    r = _command("hashes", json.dumps(jobs))
    assert r.returncode == 0, r.stderr
    registered = json.loads(r.stdout)
    for job in jobs:
        here = config_hash(OmegaConf.to_container(compose_config(job), resolve=True))
        assert registered[" ".join(job)] == here, job
        if " ".join(job) in pinned:
            assert here == pinned[" ".join(job)], job


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    run = tmp_path_factory.mktemp("throwaway") / "run"
    r = _command("mcsweep", "experiment=throwaway", SEARCH, f"hydra.run.dir={run}", "execution.progress=false")
    assert r.returncode == 0, r.stderr
    return run


def test_the_throwaway_experiment_runs_through_the_cli(run_dir):
    table = pd.read_csv(run_dir / "throwaway.csv")
    # 2000 standard normal draws: the mean within 5 standard errors of 0, the standard deviation of 1.
    assert table["n"].item() == 2000
    assert abs(table["mean"].item()) < 5 * table["mean_error"].item()
    assert abs(table["std"].item() - 1.0) < 5 / (2 * 2000) ** 0.5
    prov = json.loads((run_dir / "provenance.json").read_text())
    assert prov["kind"] == "throwaway" and "throwaway" in prov["seeds"]
    assert "Throwaway experiment" in (run_dir / "report.md").read_text()


def test_the_throwaway_experiment_resumes_keeping_its_chunks(run_dir):
    chunks = sorted((run_dir / "throwaway_chunks").glob("chunk*.parquet"))
    assert len(chunks) == 4
    before = {p.name: p.stat().st_mtime_ns for p in chunks}
    table = (run_dir / "throwaway.csv").read_bytes()
    r = _command("mcsweep", "experiment=throwaway", SEARCH, f"hydra.run.dir={run_dir}", "execution.progress=false")
    assert r.returncode == 0, r.stderr
    assert {p.name: p.stat().st_mtime_ns for p in (run_dir / "throwaway_chunks").glob("chunk*.parquet")} == before
    assert (run_dir / "throwaway.csv").read_bytes() == table


def test_another_config_in_the_same_directory_is_refused_in_one_line(run_dir):
    listing = sorted(p.name for p in run_dir.rglob("*"))
    r = _command("mcsweep", "experiment=throwaway", SEARCH, f"hydra.run.dir={run_dir}", "execution.progress=false",
                 "experiment.throwaway.per_chunk=50")
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "holds results of a different config (experiment.throwaway.per_chunk: 500 -> 50)" in lines[0]
    assert sorted(p.name for p in run_dir.rglob("*")) == listing


def test_the_report_command_rebuilds_the_throwaway_report(run_dir):
    (run_dir / "report.md").unlink()
    r = _command("report", str(run_dir))
    assert r.returncode == 0, r.stderr
    assert "Throwaway experiment" in (run_dir / "report.md").read_text()


def test_an_unknown_experiment_is_refused_naming_the_registered_ones():
    r = _command("mcsweep", "experiment=throwaway", SEARCH, "experiment.name=nonesuch")
    assert r.returncode == 2
    assert "experiment='nonesuch' is not accepted; expected one of 'f90_sweep'" in r.stderr
    assert "'throwaway' (a test's throwaway experiment)" in r.stderr
