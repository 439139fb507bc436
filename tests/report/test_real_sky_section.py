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


def _colour_run_dir(tmp_path):
    """real_sky.csv with BP-RP bins: prior 'fitted' at 0.9 inside everywhere, 'colour_mean'
    at 0.89 with a p90 error 0.6 x the fitted one's."""
    rows = [dict(truth=truth, case=case, prior=prior, b_band_deg=band, g_bin=g, colour_bin=c, n_valid=50,
                 fraction_inside=0.9 if prior == "fitted" else 0.89, fraction_lo=0.85, fraction_hi=0.93,
                 p_error_mas=5.0 if prior == "fitted" else 3.0)
            for truth, case, prior, band, g, c in itertools.product(
                ("hipparcos", "perturbed"), ("two",), ("fitted", "colour_mean"), ("all", "0-15", "15-35", "35-90"),
                ("6-7", "7-8", "6-8", "all"), ("all", "blue", "middle", "red"))]
    pd.DataFrame(rows).to_csv(tmp_path / "real_sky.csv", index=False)
    pd.DataFrame([dict(b_band_deg="all", g_bin="all", n_stars=10, median_parallax_error_mas=0.8,
                       error_over_sigma_fitted=0.3)]).to_csv(tmp_path / "real_sky_errors.csv", index=False)
    return tmp_path


def test_bp_rp_bins_give_a_table_and_a_figure_per_band_and_bin(tmp_path):
    from mcsweep.experiments.real_sky import COLOUR_FIGURE

    doc = Document("t")
    real_sky_section(doc, _colour_run_dir(tmp_path), {"config": {"confidence": 0.9}, "derived": {}})
    md = doc.to_markdown()
    assert (tmp_path / COLOUR_FIGURE).is_file() and f"({COLOUR_FIGURE})" in md
    assert "| colour_mean | 15-35 | 89.0 [85.0-93.0] / 3 (n=50) |" in md and "G 6-8" in md
    assert "prior 'colour_mean': 9 of 9 cells at 88-92 % inside" in md
    assert "the p90 position error is 0.60 x over all stars and 0.60-0.60 x per |b| band x BP-RP bin" in md
    # the rows of every colour stay the headline's and the tables' (one row per band)
    assert "prior 'fitted': all sky 90.0 [85.0-93.0] %" in md


def test_without_bp_rp_bins_no_colour_figure(tmp_path):
    from mcsweep.experiments.real_sky import COLOUR_FIGURE

    doc = Document("t")
    real_sky_section(doc, _run_dir(tmp_path), {"config": {"confidence": 0.9}, "derived": {}})
    assert not (tmp_path / COLOUR_FIGURE).exists() and "BP-RP bin" not in doc.to_markdown()
