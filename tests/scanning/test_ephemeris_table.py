"""The shipped observer tabulation is astropy's built-in ephemeris at its epochs."""

import numpy as np

from mcsweep.scanning import ephemeris

#: au. The table is written by the same astropy call; across astropy/erfa versions the
#: built-in ephemeris (epv00) may differ by rounding only (~1e-16 au).
TOL_AU = 1e-12


def test_shipped_table_is_the_builtin_ephemeris():
    jd = ephemeris.table_epochs()
    with ephemeris.table_path().open("rb") as f:
        table = np.load(f)
        gaia, sun = table["gaia_au"], table["sun_au"]
    assert gaia.shape == sun.shape == (jd.size, 3)
    pick = np.random.default_rng(2026).choice(jd.size, 400, replace=False)
    ref_gaia, ref_sun = ephemeris.compute_table(jd[pick])
    np.testing.assert_allclose(gaia[pick], ref_gaia, rtol=0, atol=TOL_AU)
    np.testing.assert_allclose(sun[pick], ref_sun, rtol=0, atol=TOL_AU)


def test_gaia_is_near_l2():
    # 1.01 x the Sun-EMB distance from the Sun (de Bruijne 2012): ~1.01 au from the Sun.
    r = np.linalg.norm(ephemeris.gaia_position_au(ephemeris.table_epochs()[::500])
                       - ephemeris.sun_position_au(ephemeris.table_epochs()[::500]), axis=1)
    assert np.all((r > 0.99) & (r < 1.03))
