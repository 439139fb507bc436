"""The ``mcsweep`` entry point end to end: outputs, resume, n_jobs invariance, bad input."""

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

BIN = Path(sys.executable).parent
#: What the sweep writes when it aggregates its cells (the fit of Eqs. 14-17, Sect. 3.4).
FIT_FILES = ("f90_cells.csv", "coefficients.csv", "rms_dex.csv", "eq14_terms.csv", "prior_maps.fits")
SMALL = [
    "sky=custom", "sky.directions=[[245.7,46.5],[30,-20],[120,5],[300,60]]",
    "magnitudes.edges=[13,14,15,16,17]", "prior_grid.n=13",
    "cell.max_stars=300", "cell.min_stars=150", "execution.progress=false",
]


def run(args, **kw):
    return subprocess.run([str(BIN / "mcsweep"), *args], capture_output=True, text=True, timeout=600, **kw)


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "sweep"
    # The usual umask, stated so the mode test below does not depend on the caller's shell.
    r = run([f"hydra.run.dir={out}", *SMALL, "execution.n_jobs=2"], umask=0o022)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.mark.slow
def test_small_sweep_writes_cells_coefficients_and_report(small_run):
    cells = sorted((small_run / "cells").glob("cell_*.parquet"))
    assert len(cells) == 4 * 4
    for name in ("cells.parquet", "coefficients.csv", "f90_cells.csv", "rms_dex.csv", "report.md",
                 "report.html", "provenance.json", "figures/fig1_curves.png", "figures/fig3_cases.png"):
        assert (small_run / name).exists(), name
    coef = pd.read_csv(small_run / "coefficients.csv")
    # Read by column name (new columns may be added): the fit and its bootstrap interval.
    assert {"term", "fitted", "paper", "difference", "fitted_lo", "fitted_hi", "paper_inside"} <= set(coef.columns)
    assert len(coef) == 9
    table = pd.read_parquet(small_run / "cells.parquet")
    assert set(table["case"]) == {"one", "two", "two_diluted", "four", "eight"}
    assert table["fraction_inside"].between(0, 1).all()
    report = (small_run / "report.md").read_text()
    assert "Provenance" in report


@pytest.mark.slow
def test_report_says_where_the_eight_case_leaves_table_1(small_run):
    # Independent reference: the paper's Table 1 lists the groups of the showcase star on
    # ... 2015-11-09 and 2015-12-29; the flown law adds a visit on 2015-12-05 in between.
    groups = pd.read_csv(small_run / "showcase" / "groups.csv")
    assert groups["first_utc"].str[:10].tolist()[6:9] == ["2015-11-09", "2015-12-05", "2015-12-29"]
    report = (small_run / "report.md").read_text()
    assert "Visits here that Table 1 lacks: 2015-12-05; Table 1 groups not found here: none" in report
    assert "the 'eight' case ends on 2015-12-05 instead of 2015-12-29" in report


@pytest.mark.slow
def test_report_summarises_the_manifest_which_stays_in_provenance(small_run):
    report = (small_run / "report.md").read_text()
    # The report summarises the computation's files as they were when it was written
    # (the report stage's own outputs come after it).
    # The sweep's results: its cells, the showcase, and the fit of Eqs. 14-17 with its maps.
    manifest = [m for m in json.loads((small_run / "provenance.json").read_text())["manifest"]
                if m["path"].startswith(("cells/", "cells.parquet", "showcase/")) or m["path"] in FIT_FILES]
    assert len(manifest) == 4 * 4 + 1 + len(list((small_run / "showcase").glob("*"))) + len(FIT_FILES)
    assert "cells/cell_" not in report  # no file-by-file listing in the report
    assert f"Result files of the computation (before this report): {len(manifest)} files" in report
    digest = hashlib.sha256("\n".join(sorted(f"{m['path']}:{m['sha256']}" for m in manifest)).encode())
    assert digest.hexdigest()[:16] in report


@pytest.mark.slow
def test_provenance_records_the_galaxy_model_version(small_run):
    from mcsweep.population.galaxy.parameters import MODEL_VERSION

    record = json.loads((small_run / "provenance.json").read_text())
    assert record["galaxy_model_version"] == MODEL_VERSION
    assert record["config"]["population"]["params"]["thin_disc_scale_height_factor"] == 1.15


@pytest.mark.slow
def test_result_files_are_readable_by_group_and_others_under_umask_022(small_run):
    files = [p for p in small_run.rglob("*") if p.is_file()]
    assert len(files) > 20
    private = [str(p.relative_to(small_run)) for p in files if (p.stat().st_mode & 0o777) != 0o644]
    assert not private, private


@pytest.mark.slow
def test_rerun_skips_finished_cells_and_njobs_does_not_matter(small_run, tmp_path):
    before = {p.name: p.stat().st_mtime_ns for p in (small_run / "cells").glob("*.parquet")}
    # A run resumed after all its cells are done still writes the fit (not the report):
    # the same bytes again.
    fit_bytes = {name: (small_run / name).read_bytes() for name in FIT_FILES}
    for name in FIT_FILES:
        (small_run / name).unlink()
    r = run([f"hydra.run.dir={small_run}", *SMALL, "execution.n_jobs=2"])
    assert r.returncode == 0, r.stderr[-2000:]
    after = {p.name: p.stat().st_mtime_ns for p in (small_run / "cells").glob("*.parquet")}
    assert before == after  # nothing recomputed
    assert {name: (small_run / name).read_bytes() for name in FIT_FILES} == fit_bytes
    one = tmp_path / "one"
    r = run([f"hydra.run.dir={one}", *SMALL, "execution.n_jobs=1"])
    assert r.returncode == 0, r.stderr[-2000:]
    a = pd.read_parquet(small_run / "cells.parquet").sort_values(["cell_id", "case", "sigma_prior_mas"])
    b = pd.read_parquet(one / "cells.parquet").sort_values(["cell_id", "case", "sigma_prior_mas"])
    pd.testing.assert_frame_equal(a.reset_index(drop=True), b.reset_index(drop=True), check_exact=True)


@pytest.mark.slow
def test_changed_config_in_same_run_dir_is_refused(small_run):
    r = run([f"hydra.run.dir={small_run}", *SMALL, "confidence=0.8"])
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.strip().splitlines() if ln]
    assert len(lines) == 1 and "different config" in lines[0] and "confidence" in lines[0]


@pytest.mark.parametrize("bad", [
    ["confidence=1.5"], ["cell.beam_radius_deg=-1"], ["sky=nowhere"], ["magnitudes.edges=[24,26]"],
    ["population=catalogue", "population.path=/nonexistent/stars.csv"],
])
def test_bad_overrides_exit_2_with_one_line_and_no_output(tmp_path, bad):
    out = tmp_path / "bad"
    r = run([f"hydra.run.dir={out}", *bad])
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    lines = [ln for ln in r.stderr.strip().splitlines() if ln]
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.stderr
    assert not out.exists()


@pytest.mark.slow
def test_dask_info_lines_go_to_the_log_file_not_the_terminal(tmp_path):
    pytest.importorskip("dask.distributed")
    out = tmp_path / "dask"
    r = run([f"hydra.run.dir={out}", "sky=custom", "sky.directions=[[245.7,46.5]]", "magnitudes.edges=[14,15]",
             "prior_grid.n=7", "cell.max_stars=100", "cell.min_stars=50", "execution=dask",
             "execution.n_jobs=2", "execution.progress=false"])
    assert r.returncode == 0, r.stderr[-2000:]
    terminal = r.stdout + r.stderr
    # Warnings stay visible by design (e.g. a nanny killing a slow worker on a loaded
    # machine); INFO lines of third-party loggers must not reach the terminal.
    third_party_info = [ln for ln in terminal.splitlines() if "distributed." in ln and "WARNING" not in ln
                        and "ERROR" not in ln]
    assert not third_party_info, terminal[:2000]
    assert terminal.strip().splitlines()[-1].startswith("mcsweep: results in")
    log = "".join(p.read_text() for p in out.glob("*.log"))
    assert "distributed.scheduler" in log  # kept in the run's log


@pytest.mark.slow
def test_sweep_writes_prior_maps_equal_to_prior_from_run(small_run):
    import numpy as np
    from astropy.coordinates import Galactic
    from astropy.io import fits
    from astropy_healpix import HEALPix

    from mcsweep.prior import Prior

    rtol_paths = 1e-13  # same formula, array vs scalar numpy kernels
    prior = Prior.from_run(small_run)
    assert (prior.g_min, prior.g_max, prior.confidence, prior.ratio_R) == (13.0, 17.0, 0.9, 10.0)
    with fits.open(small_run / "prior_maps.fits") as hdul:
        h = hdul["SIGMA_F90"].header
        assert (h["NSIDE"], h["ORDERING"], h["COORDSYS"]) == (16, "RING", "G")
        hp = HEALPix(nside=h["NSIDE"], order="ring", frame=Galactic())
        lon, lat = hp.healpix_to_lonlat(np.arange(hp.npix))
        gs = [h[f"GMAG{i}"] for i in range(1, h["TFIELDS"] + 1)]
        assert gs == [13.5, 14.5, 15.5, 16.5]
        for i, g in enumerate(gs):
            np.testing.assert_allclose(hdul[1].data.field(i), prior.sigma_parallax(lon, lat, G=g).value,
                                       rtol=rtol_paths, atol=0)
        assert len(hdul["CELLS"].data) == 16
    assert (small_run / "figures" / "prior_maps.png").exists()
    assert "figures/prior_maps.png" in (small_run / "report.md").read_text()


@pytest.mark.slow
def test_default_run_is_not_extrapolated_and_names_each_visits_segment(small_run):
    # The paper's window lies inside the flown law's 2014-09-25 - 2017-01-27 segment (scanning-law-history.md).
    prov = json.loads((small_run / "provenance.json").read_text())
    assert prov["derived"]["scanning"] == {"extrapolated": None}
    groups = pd.read_csv(small_run / "showcase" / "groups.csv")
    assert set(groups["segment"]) == {"nsl 2014-09-25..2017-01-27"}
    assert "extrapolated" not in (small_run / "report.md").read_text()


@pytest.mark.slow
def test_nominal_law_and_a_window_outside_the_mission_are_said_extrapolated(tmp_path):
    tiny = ["sky=single", "magnitudes.edges=[14,15]", "prior_grid.n=5", "cell.max_stars=100",
            "cell.min_stars=50", "cell.n_bootstrap=0", "experiment.showcase.enabled=false",
            "execution.progress=false", "execution.n_jobs=1"]
    for name, extra in (("nominal", ["scanning=nominal"]),
                        ("late", ["observations.start=2025-01-01T00:00:00", "observations.end=2025-06-01T00:00:00"])):
        out = tmp_path / name
        r = run([f"hydra.run.dir={out}", *tiny, *extra])
        assert r.returncode == 0, r.stderr[-3000:]
        note = json.loads((out / "provenance.json").read_text())["derived"]["scanning"]["extrapolated"]
        assert "extrapolated" in note
        assert "Scanning law: " + note in (out / "report.md").read_text()
        assert note in r.stderr + r.stdout + "".join(p.read_text() for p in out.glob("*.log"))
