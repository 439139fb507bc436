"""The README's first command installs non-editable: the built wheel must run a sweep.

An editable install reads configs and data files from the source tree, so a file left
out of the package data would pass every other test and still break users. This test
builds the wheel as ``pip install .`` does, installs it into a fresh virtualenv and
runs a tiny sweep from there, outside the source tree.

The build must also be free of setuptools deprecations: each one announces a date after
which a fresh clone stops building (the TOML-table ``project.license``: "By 2027-Feb-18
... your builds will no longer be supported"). pip shows the backend's output only with
``-v``, so the build runs verbosely and its output is searched.
"""

import shutil
import site
import subprocess
import sys
import sysconfig
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
SKIP = shutil.ignore_patterns(".venv", ".git", "results", "build", "dist", "*.egg-info", "__pycache__",
                              ".pytest_cache", ".hypothesis", "tests", "benchmarks")


def _sh(args, **kw):
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=900, **kw)
    assert r.returncode == 0, f"{args}\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
    return r


@pytest.mark.slow
def test_wheel_in_a_fresh_virtualenv_runs_a_tiny_sweep(tmp_path):
    src = tmp_path / "src_copy"
    shutil.copytree(ROOT, src, symlinks=True, ignore=SKIP)  # build outside the work tree
    built = _sh([sys.executable, "-m", "pip", "wheel", "--no-deps", "-v", "-w", tmp_path / "dist", src])
    output = built.stdout + built.stderr
    deprecations = [line.strip() for line in output.splitlines() if "SetuptoolsDeprecationWarning" in line]
    assert not deprecations, "the build uses something setuptools will drop:\n" + "\n".join(deprecations)
    wheels = list((tmp_path / "dist").glob("mcsweep-*.whl"))
    assert len(wheels) == 1

    venv = tmp_path / "venv"
    _sh([sys.executable, "-m", "venv", "--without-pip", venv])
    py = venv / "bin" / "python"
    purelib = Path(_sh([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
    # Dependencies come from this test environment's site-packages through a .pth file;
    # .pth files inside that directory (our own editable install) are not processed.
    deps = [sysconfig.get_paths()["purelib"], *site.getsitepackages()]
    (purelib / "_mcsweep_test_deps.pth").write_text("\n".join(dict.fromkeys(deps)) + "\n")
    _sh([sys.executable, "-m", "pip", "--python", py, "install", "--no-deps", "-q", wheels[0]])

    where = _sh([py, "-c", "import mcsweep; print(mcsweep.__file__)"], cwd=tmp_path).stdout.strip()
    assert Path(where).is_relative_to(venv), where  # the wheel's copy, not the source tree

    run_dir = tmp_path / "run"
    _sh([venv / "bin" / "mcsweep", f"hydra.run.dir={run_dir}", "sky=single", "magnitudes=g15",
         "prior_grid.n=9", "cell.max_stars=200", "cell.min_stars=100", "execution.n_jobs=1",
         "execution.progress=false"], cwd=tmp_path)
    assert (run_dir / "report.md").stat().st_size > 0 and (run_dir / "report.html").exists()
    coef = pd.read_csv(run_dir / "coefficients.csv")
    assert {"term", "fitted", "paper"} <= set(coef.columns) and len(coef) == 9
