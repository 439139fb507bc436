"""The owner of a sweep run's files (prior.run_record): the names the sweep writes and every
reader reads, the coefficient schema of Eqs. 15-17, and the run's record, with one line for
a directory that is not a finished sweep."""

import json

import pandas as pd
import pytest

from mcsweep.errors import UserInputError
from mcsweep.experiments.f90_sweep import FIT_FILES
from mcsweep.prior import PAPER_COEFFICIENTS
from mcsweep.prior import run_record as R


def _provenance(path, **config):
    path.mkdir(exist_ok=True)
    (path / R.PROVENANCE_FILE).write_text(json.dumps({"kind": "f90_sweep", "config": config}))
    return path


def test_the_schema_is_eqs_15_to_17():
    # Eq. 15 quadratic in G, Eq. 16 cubic, Eq. 17 linear: the paper's own coefficient table
    assert {k: len(v) for k, v in PAPER_COEFFICIENTS.items()} == R.N_COEFFICIENTS
    assert R.N_COEFFICIENTS == {k: d + 1 for k, d in R.POLY_DEGREES.items()}
    assert R.COEFFICIENTS_FILE in FIT_FILES


def test_coefficients_read_back_as_written(tmp_path):
    rows = [(f"{k}_c{i}", c) for k, cs in PAPER_COEFFICIENTS.items() for i, c in enumerate(cs)]
    pd.DataFrame(rows, columns=["term", "fitted"]).to_csv(tmp_path / R.COEFFICIENTS_FILE, index=False)
    got = R.read_coefficients(tmp_path / R.COEFFICIENTS_FILE)
    assert got.keys() == PAPER_COEFFICIENTS.keys()
    for k in PAPER_COEFFICIENTS:
        assert got[k] == tuple(float(c) for c in PAPER_COEFFICIENTS[k])


def test_the_record_says_what_the_run_was_made_with(tmp_path):
    run = _provenance(tmp_path / "run", magnitudes={"edges": [6, 7, 8]}, confidence=0.8, ratio_R=5,
                      prior_model={"name": "colour_mean", "colour_edges": [-1, 0.56, 6], "mean": True},
                      observations={"f90_case": "one"})
    rec = R.read_record(run)
    assert (rec.prior_model_name, rec.colour_edges, rec.mean) == ("colour_mean", [-1, 0.56, 6], True)
    assert (rec.g_edges, rec.confidence, rec.ratio_R, rec.f90_case) == ([6, 7, 8], 0.8, 5.0, "one")
    # a run made before prior_model existed: the paper's colour-blind, zero-centred prior
    old = R.read_record(_provenance(tmp_path / "old", magnitudes={"edges": [6, 7]}))
    assert (old.prior_model_name, old.colour_edges, old.mean, old.confidence) == ("direction_g", [], False, None)


@pytest.mark.parametrize("content, word", [
    (None, "no provenance.json"),
    ("not json", "cannot read provenance.json"),
    ("[1, 2]", "not a run record"),
    (json.dumps({"kind": "secondary", "config": {}}), "'secondary' run"),
    (json.dumps({"kind": "f90_sweep", "config": {}}), "no magnitudes.edges"),
])
def test_not_a_sweep_is_one_line(tmp_path, content, word):
    if content is not None:
        (tmp_path / R.PROVENANCE_FILE).write_text(content)
    with pytest.raises(UserInputError, match=word) as err:
        R.read_record(tmp_path, "expected a sweep")
    assert "\n" not in str(err.value) and str(err.value).endswith("expected a sweep")
