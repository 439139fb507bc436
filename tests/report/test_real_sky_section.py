"""The real-sky report section says what every global section says about the scanning law:
run_global records the extrapolation note for the real-sky run as for the others."""

import itertools

import pandas as pd
import pytest

from mcsweep.runtime.document import Document
from mcsweep.experiments.real_sky.section import real_sky_section
from mcsweep.scanning.law import ScanningLaw


def _run_dir(tmp_path):
    rows = [dict(truth=truth, case=case, prior=prior, b_band_deg=band, g_bin=g, fraction_inside=0.9,
                 fraction_lo=0.88, fraction_hi=0.92, p_error_mas=0.5)
            for truth, case, prior, band, g in itertools.product(("hipparcos", "perturbed"), ("two", "all"),
                                                                  ("F90",), ("all", "0-15", "15-90"),
                                                                  ("all", "6-8"))]
    pd.DataFrame(rows).to_csv(tmp_path / "real_sky.csv", index=False)
    pd.DataFrame([dict(b_band_deg="all", g_bin="all", n_stars=10, median_parallax_error_mas=0.8,
                       error_over_sigma_F90=0.3)]).to_csv(tmp_path / "real_sky_errors.csv", index=False)
    return tmp_path


@pytest.mark.parametrize("law, start_jd, end_jd", [("nominal", 2457023.5, 2457100.5),
                                                  ("flown", 2456000.5, 2457100.5)])
def test_the_scanning_laws_extrapolation_note_is_in_the_section(tmp_path, law, start_jd, end_jd):
    # The note as the scanning law itself words it (what run_global stores in provenance).
    note = ScanningLaw.preset(law).extrapolation_note(start_jd, end_jd)
    assert note and "extrapolated" in note
    prov = {"config": {"confidence": 0.9}, "derived": {"scanning": {"extrapolated": note}}}
    doc = Document("t")
    real_sky_section(doc, _run_dir(tmp_path), prov)
    md = doc.to_markdown()
    assert f"Scanning law: {note}." in md
    # in the headline, before the setup and its tables
    assert md.index(note) < md.index("Setup and tables")


def test_no_note_when_nothing_is_extrapolated(tmp_path):
    doc = Document("t")
    real_sky_section(doc, _run_dir(tmp_path), {"config": {}, "derived": {"scanning": {"extrapolated": None}}})
    assert "Scanning law:" not in doc.to_markdown()
