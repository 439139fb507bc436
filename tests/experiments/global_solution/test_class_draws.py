"""The global experiments' classes of stars drawn as executor tasks: the same stars,
bit for bit, whether drawn in this process, by loky workers or on a Dask cluster, and a
worker's warning reaches the user."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from mcsweep.experiments.global_solution.classes import draw_classes
from mcsweep.runtime.execution import executor
from mcsweep.command.validate import compose_config, to_config

GALAXY = {"name": "galaxy_model"}
GROUPS = [(15.0, 300, 1500), (19.0, 200, 1900)]


def _seed(key: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(20150821, spawn_key=(42, 0, key))


def _execution(*overrides):
    return to_config(compose_config(["execution.progress=false", *overrides])).execution


def _draws(population, run=None, groups=GROUPS):
    return draw_classes(population, groups, _seed, size_key="experiment.primary.class_size", run=run)


def _assert_same(a, b):
    assert [(g, k) for g, k, _ in a] == [(g, k) for g, k, _ in b]
    for (_, _, x), (_, _, y) in zip(a, b):
        pd.testing.assert_frame_equal(x, y, check_exact=True)
        assert x.attrs["g_upper"] == y.attrs["g_upper"]


@pytest.mark.parametrize("backend", ["local", "dask"])
def test_classes_drawn_by_workers_are_the_ones_drawn_here(backend):
    here = _draws(GALAXY)
    assert [len(s) for _, _, s in here] == [300, 200]
    with executor(_execution(f"execution={backend}", "execution.n_jobs=2"), release_workers=True) as run:
        there = _draws(GALAXY, run)
    _assert_same(there, here)


def test_a_workers_warning_is_repeated_here(tmp_path):
    rng = np.random.default_rng(4)
    n = 50
    path = tmp_path / "stars.csv"
    pd.DataFrame({"ra": rng.uniform(0, 360, n), "dec": rng.uniform(-60, 60, n), "parallax": rng.uniform(0.1, 3, n),
                  "pmra": rng.normal(0, 5, n), "pmdec": rng.normal(0, 5, n),
                  "phot_g_mean_mag": rng.uniform(10, 20, n)}).to_csv(path, index=False)
    population = {"name": "catalogue", "path": str(path)}
    with warnings.catch_warnings(record=True) as caught, \
            executor(_execution("execution=local", "execution.n_jobs=2"), release_workers=True) as run:
        warnings.simplefilter("always")
        got = _draws(population, run, groups=[(15.0, 1000, 1500)])
    messages = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert len(got[0][2]) < 1000
    assert any("fewer than experiment.primary.class_size=1000" in m for m in messages), messages
