"""Pieces of the validation script that are cheap enough for the test suite."""

import numpy as np

from mcsweep.population import GalaxyModel
from mcsweep.validation.population_validation import healpix48_centres, ratio_table

#: The paper's footnote (Sect. 3.4): sigma_F90 is 0.5-0.8 x p90(parallax) in GUMS; accept 0.4-1.0 in most cells.
MIN_FRACTION_IN_RANGE = 0.8


def test_healpix_directions_are_48_distinct_and_uniform():
    l, b = healpix48_centres()
    assert len(l) == 48 and len({(round(x, 6), round(y, 6)) for x, y in zip(l, b)}) == 48
    assert abs(np.mean(np.sin(np.radians(b)))) < 1e-9   # symmetric about the plane


def test_footnote_ratio_at_g15():
    cells = ratio_table(GalaxyModel(), np.random.default_rng(15), g_centres=[15])
    assert len(cells) == 48 and (cells.n_drawn > 100).all()
    inside = cells.ratio.between(0.4, 1.0).mean()
    assert inside >= MIN_FRACTION_IN_RANGE, cells.sort_values("ratio")


def test_the_calibration_section_writes_its_tables_and_figures(tmp_path):
    from mcsweep.validation.population_validation import published_section

    lines = published_section(tmp_path, GalaxyModel(), np.random.default_rng(14))
    for name in ("published_counts.csv", "published_counts.png", "local_lf.csv", "local_lf.png",
                 "local_census.csv", "bright_parallax.csv", "local_density_by_class.csv",
                 "local_density_by_class.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    text = "\n".join(lines)
    assert "Bovy 2017 MS" in text and "GCNS 60 pc" in text and "CNS5 25 pc" in text
    assert "Local density per spectral class" in text and "M + white dwarfs (CNS5)" in text


def test_an_out_that_is_a_file_is_one_line_and_exit_2(tmp_path, capsys):
    from mcsweep.validation.population_validation import main

    taken = tmp_path / "a_file"
    taken.write_text("x")
    assert main(["--out", str(taken)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("population_validation: --out=") and "a_file" in err[0]
    assert taken.read_text() == "x"
