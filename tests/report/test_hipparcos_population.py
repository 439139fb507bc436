"""report.hipparcos_population on a small draw (issue 25): the Hipparcos side is the
bundled catalogue, the model side its expectation and a seeded sample."""

import numpy as np
import pytest

from mcsweep.population import GalaxyModel
from mcsweep.report import hipparcos_population as hp

#: Hipparcos 2 stars with 6 <= G < 7 per |b| band 0-15 / 15-35 / 35-90 deg (the real-sky
#: validation's counts of the same catalogue, docs/galaxy_model.md).
HIP_G67 = (4879, 4291, 4257)
N_DRAW = 5000


@pytest.fixture(scope="module")
def table():
    return hp.compare(GalaxyModel(), n_draw=N_DRAW)


def test_one_row_per_g_bin_and_band_with_the_catalogue_counts(table):
    assert len(table) == len(hp.G_BINS) * len(hp.BANDS_DEG)
    g67 = table[table.g_min == 6.0]
    assert tuple(g67.n_hip) == HIP_G67
    assert np.all(np.isfinite(table[["count_ratio", "plx90_ratio", "pm50_ratio"]].to_numpy()))


def test_model_counts_per_band_add_up_to_its_expectation(table):
    model = GalaxyModel()
    for (g0, g1), part in table.groupby(["g_min", "g_max"]):
        assert part.n_model.sum() == pytest.approx(model.expected_count(0, 90, 180, g0, g1), rel=1e-9)


def test_seeded_and_ratios_consistent(table):
    again = hp.compare(GalaxyModel(), n_draw=N_DRAW)
    assert again.equals(table)
    assert np.allclose(table.plx90_ratio, table.plx90_model / table.plx90_hip)


def test_bad_options_exit_2(capsys):
    assert hp.main(["--extinction-model", "schlegel"]) == 2
    assert "extinction_model" in capsys.readouterr().err
    assert hp.main(["--giant-thickness-factor", "0"]) == 2
    assert hp.main(["--n-draw", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("hipparcos_population:") for line in err)
