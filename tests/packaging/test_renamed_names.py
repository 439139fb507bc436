"""Renamed public names keep working under their old names, with one deprecation warning."""

from __future__ import annotations

import importlib

import pytest

RENAMED = [
    ("mcsweep.experiments.f90_sweep.pencil_beam", "MEAN_COLUMNS", "CELL_MEAN_COLUMNS"),
    ("mcsweep.prior.means", "MEAN_COLUMNS", "MEANS_TABLE_COLUMNS"),
    ("mcsweep.prior.annotate", "MEAN_COLUMNS", "PRIOR_MEAN_COLUMNS"),
    ("mcsweep.solver", "Observations", "Measurements"),
    ("mcsweep.solver", "build_observations", "build_measurements"),
    ("mcsweep.solver.observations", "Observations", "Measurements"),
    ("mcsweep.solver.observations", "build_observations", "build_measurements"),
    ("mcsweep.prior.observations", "Observations", "TransitTable"),
]


@pytest.mark.parametrize("module, old, new", RENAMED)
def test_an_old_name_gives_the_new_object_with_a_warning_naming_both(module, old, new):
    mod = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=rf"{module}\.{old} is deprecated: use {module}\.{new}"):
        value = getattr(mod, old)
    assert value is getattr(mod, new)
    with pytest.raises(AttributeError, match="no_such_name"):
        getattr(mod, "no_such_name")

