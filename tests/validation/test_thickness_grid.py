"""validation.thickness_grid: the vertical heights the thickness factors imply."""

import pytest

from mcsweep.population import GalaxyModel
from mcsweep.population.galaxy import parameters as P
from mcsweep.validation import thickness_grid as tg

#: Relative agreement of heights that scale with a factor: approximate, as the Einasto law
#: (a^2 = R^2 + z^2 / eps^2) is not self-similar in z alone (measured: 1.00-1.05 x for the
#: giants, up to 1.26 / 1.2 for the thin disc).
SCALING_TOL = 0.10


def test_heights_follow_their_own_factor_only():
    base = tg.vertical_heights_pc(GalaxyModel())
    thick_giants = tg.vertical_heights_pc(GalaxyModel(giant_thickness_factor=2.0 * P.GIANT_THICKNESS_FACTOR))
    thick_disc = tg.vertical_heights_pc(
        GalaxyModel(thin_disc_scale_height_factor=P.THIN_DISC_THICKNESS_FACTOR * 1.2))
    # the giants' factor moves the giants alone, about in proportion
    assert thick_giants[1:] == base[1:]
    assert thick_giants[0] / base[0] == pytest.approx(2.0, rel=SCALING_TOL)
    # the thin-disc factor moves dwarfs and giants alike
    for new, old in zip(thick_disc, base):
        assert new / old == pytest.approx(1.2, rel=SCALING_TOL)
    # the default model's thin-disc dwarfs against Juric et al. (2008): 300 pc
    assert base[1] == pytest.approx(300.0, rel=0.10)


def test_bad_factor_list_exits_2(capsys):
    assert tg.main(["--giant", "0.5,x"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--giant" in err and "\n" not in err
    assert tg.main(["--thin", "-1"]) == 2


def test_unwritable_out_exits_2_before_computing(tmp_path, capsys):
    # one line, status 2, and nothing computed (the grid takes ~5 s per pair)
    assert tg.main(["--giant", "0.45", "--thin", "1.15", "--out", str(tmp_path / "missing" / "grid.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--out" in err[0]


def test_fitted_thicknesses_agree_with_bovys_scale_heights():
    # Check, not fit: the giants' and young disc's factors were set against Gaia DR3 counts per
    # colour (validation.dr3_colours); Bovy (2017, abstract) measured sech^2 scale heights of ~150 pc
    # for giants and ~50 pc for A stars. Read as sech^2(z / 2h), the density halves at 1.763 h:
    # 264 and 88 pc. "~" values: 20 %.
    m = GalaxyModel()
    giants_zhalf = tg.vertical_heights_pc(m)[0]
    assert giants_zhalf == pytest.approx(1.763 * 150.0, rel=0.20)
    assert tg.a_star_half_height_pc(m) == pytest.approx(1.763 * 50.0, rel=0.20)
