"""The stage packages export their names lazily (mcsweep.lazy_exports): every exported name
resolves, and the config schema loads without the heavy dependencies."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

PACKAGES = ("mcsweep.astrometry", "mcsweep.scanning", "mcsweep.prior")


@pytest.mark.parametrize("name", PACKAGES)
def test_every_exported_name_resolves_to_its_modules_object(name):
    pkg = importlib.import_module(name)
    assert pkg.__all__ and set(pkg.__all__) <= set(dir(pkg))
    for attr in pkg.__all__:
        value = getattr(pkg, attr)
        home = getattr(value, "__module__", None)
        if home is not None and home.startswith(name + "."):  # a function or class: its own module's
            assert getattr(importlib.import_module(home), attr) is value
    with pytest.raises(AttributeError, match="no_such_name"):
        getattr(pkg, "no_such_name")


def test_the_config_schema_loads_without_scipy_stats_matplotlib_or_the_experiments():
    code = ("import sys, mcsweep.command.validate, mcsweep.cli; "
            "print(sorted(m for m in ('scipy.stats', 'matplotlib', 'mcsweep.experiments.primary.experiment', "
            "'mcsweep.report.build') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_a_sweep_worker_loads_neither_the_parents_modules_nor_their_dependencies():
    # A worker imports the task's module (jobs) and builds the galaxy model (with astropy's
    # frames); the fit, the report and the scanning law's integration belong to the parent.
    code = ("import sys; from mcsweep.experiments.f90_sweep import jobs; "
            "print(sorted(m for m in ('scipy.stats', 'scipy.integrate', 'scipy.interpolate', 'matplotlib', "
            "'mcsweep.experiments.f90_sweep.fit', 'mcsweep.experiments.f90_sweep.runner', "
            "'mcsweep.scanning.attitude') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]", out.stdout
