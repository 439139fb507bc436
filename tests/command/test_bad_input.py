"""Bad input through the real command line: exit status 2, one clear line, no output.

Config values and catalogue files alike (issue: at least 20 cases). Config values are
also checked faster, and more of them, in test_config.py; here every case goes through
the ``mcsweep`` entry point as a user would run it.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from astropy import units as u
from astropy.table import Table

BIN = Path(sys.executable).parent
N = 300


def _stars(**over):
    rng = np.random.default_rng(7)
    # Around the paper's Table 1 beam (ra, dec) = (157.5, 0) so a valid file would be usable.
    d = dict(ra=rng.uniform(156, 159, N), dec=rng.uniform(-1.5, 1.5, N), parallax=rng.uniform(0.1, 3, N),
             pmra=rng.normal(0, 5, N), pmdec=rng.normal(0, 5, N), phot_g_mean_mag=rng.uniform(14.5, 15.5, N))
    d.update(over)
    return d


def _csv(path, **over):
    pd.DataFrame(_stars(**over)).to_csv(path, index=False)
    return path


def _missing_column(p):
    d = _stars()
    del d["parallax"]
    pd.DataFrame(d).to_csv(p / "nopar.csv", index=False)
    return p / "nopar.csv", "parallax"


def _nans(p):
    plx = _stars()["parallax"]
    plx[:5] = np.nan
    return _csv(p / "nans.csv", parallax=plx), "NaN"


def _strings(p):
    pm = _stars()["pmra"].astype(object)
    pm[3] = "fast"
    return _csv(p / "strings.csv", pmra=pm), "pmra"


def _parallax_in_km(p):
    t = Table(_stars())
    t["parallax"].unit = u.km
    t.write(p / "km.fits")
    return p / "km.fits", "parallax"


def _dec_in_radians_times_100(p):
    return _csv(p / "dec.csv", dec=np.full(N, 157.0)), "dec"


def _empty_cone(p):
    return _csv(p / "far.csv", ra=np.full(N, 10.0), dec=np.full(N, -60.0)), "no star"


def _unreadable(p):
    (p / "broken.fits").write_text("this is not FITS")
    return p / "broken.fits", "broken.fits"


def _unknown_format(p):
    return _csv(p / "stars.xyz"), "format"


def _absent(p):
    return p / "absent.csv", "not found"


CATALOGUES = [_missing_column, _nans, _strings, _parallax_in_km, _dec_in_radians_times_100, _empty_cone,
              _unreadable, _unknown_format, _absent]

CONFIGS = [
    (["confidence=1.5"], "confidence"), (["confidence=0"], "confidence"), (["ratio_R=0"], "ratio_R"),
    (["cell.beam_radius_deg=-1"], "beam_radius_deg"), (["cell.max_stars=0"], "max_stars"),
    (["magnitudes.edges=[15,14]"], "edges"), (["magnitudes.edges=[24,26]"], "edges"),
    (["sky=nowhere"], "sky"), (["population=gums"], "population"), (["execution.backend=spark"], "backend"),
    (["prior_grid.min_mas=-0.01"], "min_mas"), (["observations.start=2014-13-01"], "observations.start"),
    (["scanning.precession_S=0.5"], "precession_S"), (["experiment.secondary.dilution=1.5"], "dilution"),
    (["experiment=secondary", "experiment.secondary.reference_epoch=2016-02-30"], "reference_epoch"),
    (["experiment=secondary", "experiment.secondary.reference_epoch=mid"], "reference_epoch"),
]


def _run(tmp_path, args):
    out = tmp_path / "run"
    r = subprocess.run([str(BIN / "mcsweep"), f"hydra.run.dir={out}", "sky=single", "magnitudes=g15",
                        "prior_grid.n=5", "execution.n_jobs=1", *args],
                       capture_output=True, text=True, timeout=300)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    return r, lines, out


@pytest.mark.parametrize("make", CATALOGUES, ids=[f.__name__.strip("_") for f in CATALOGUES])
def test_bad_catalogue(tmp_path, make):
    path, needle = make(tmp_path)
    r, lines, out = _run(tmp_path, ["population=catalogue", f"population.path={path}"])
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert needle in lines[0] and path.name in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("args,needle", CONFIGS, ids=[" ".join(a) for a, _ in CONFIGS])
def test_bad_config_value(tmp_path, args, needle):
    r, lines, out = _run(tmp_path, args)
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert needle in lines[0]
    assert not out.exists()


def test_a_valid_catalogue_runs(tmp_path):
    """The same files minus the fault are accepted (the table above tests faults, not formats)."""
    path = _csv(tmp_path / "good.csv")
    r, _, out = _run(tmp_path, ["population=catalogue", f"population.path={path}", "cell.min_stars=100",
                                "experiment.showcase.enabled=false"])
    assert r.returncode == 0, r.stderr[-3000:]
    f90 = pd.read_csv(out / "f90_cells.csv")
    assert len(f90) == 1 and f90["n_stars"].item() > 100
