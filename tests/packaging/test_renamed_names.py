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
    ("mcsweep.scanning.transits", "DEFAULT_DEAD_TIME_BLOCK_DAYS", "DEFAULT_DEAD_TIME_OUTAGE_DAYS"),
]


@pytest.mark.parametrize("module, old, new", RENAMED)
def test_an_old_name_gives_the_new_object_with_a_warning_naming_both(module, old, new):
    mod = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=rf"{module}\.{old} is deprecated: use {module}\.{new}"):
        value = getattr(mod, old)
    assert value is getattr(mod, new)
    with pytest.raises(AttributeError, match="no_such_name"):
        getattr(mod, "no_such_name")



def test_an_old_keyword_gives_the_same_dead_time_with_a_warning_and_both_are_refused():
    import numpy as np

    from mcsweep.scanning.timeline import draw_dead_time

    new = draw_dead_time(0.0, 100.0, 0.2, outage_days=2.0, rng=np.random.default_rng(1))
    with pytest.warns(DeprecationWarning, match="keyword block_days is deprecated: use outage_days"):
        old = draw_dead_time(0.0, 100.0, 0.2, block_days=2.0, rng=np.random.default_rng(1))
    np.testing.assert_array_equal(old.starts, new.starts)
    assert new.starts.size == 10 and np.all(new.stops - new.starts == 2.0)
    with pytest.raises(TypeError, match="expected one"):
        draw_dead_time(0.0, 100.0, 0.2, block_days=2.0, outage_days=2.0, rng=np.random.default_rng(1))
    with pytest.raises(TypeError, match="missing required keyword argument: 'outage_days'"):
        draw_dead_time(0.0, 100.0, 0.2, rng=np.random.default_rng(1))
