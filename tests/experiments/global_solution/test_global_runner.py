"""The shared path of the global experiments (mcsweep.experiments.global_solution.run) and what it prints."""

import numpy as np
import pandas as pd

from mcsweep.experiments.global_solution.run import GlobalRun
from mcsweep.experiments.primary.runner import solution_line
from mcsweep.runtime.store import ResultStore


def test_solution_line_writes_the_attitude_rms_as_numbers_not_a_numpy_repr():
    extra = {"iterations": 42, "converged": True, "attitude_rms_uas": [9.5, 12.8, 13.06]}
    line = solution_line("10F90", extra)
    assert line == ("mcsweep: primary: prior 10F90: 42 PCG iterations, converged True, "
                    "attitude error RMS 9.5 / 12.8 / 13.1 uas (x / y / z)")
    # what the solver hands over: numpy floats, formatted alike
    assert solution_line("10F90", {**extra, "attitude_rms_uas": list(np.array([9.5, 12.8, 13.06]))}) == line


def test_pending_finds_the_missing_chunks_without_counting_the_finished_ones(tmp_path):
    store = ResultStore(tmp_path / "chunks", "hash0", version="v1")
    store.write("a", pd.DataFrame({"x": [1, 2]}))
    run = GlobalRun(config=None, run_dir=tmp_path, prov=None, settings=None, epoch={}, classes=[], store=store)
    assert run.pending(["a", "b"]) == ["b"]
    # a resume check is not a use: only the results read for the tables count as cells of a version
    assert not store.versions_read
    (df,) = run.read_all(["a"])
    assert df["x"].tolist() == [1, 2] and store.versions_read == {"v1": 1}
