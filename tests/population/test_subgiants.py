"""The galaxy model's subgiants from the Wielen/Allen luminosity function (population.params.subgiants
with evolved_stars=wielen; on by default in besancon-r03-5)."""

import numpy as np
import pytest

from mcsweep.population import GalaxyModel
from mcsweep.population.galaxy import luminosity as L
from mcsweep.population.galaxy import parameters as P
from mcsweep.population.galaxy.model import PARAMS_R03_5
from mcsweep.validation import hipparcos_population as hp

#: Wielen (1974) via Allen's Astrophysical Quantities, stars pc^-3 in the M_V bins centred on 2,
#: 3 and 4 (data/lf_wielen_allen.ecsv: 6, 12 and 19 x 1e-4), all luminosity classes.
WIELEN_ALLEN_MV234 = (6.0e-4, 12.0e-4, 19.0e-4)


def _bovy_ms(mv):
    """Bovy's (2017) dn/dM = 0.016 M^-4.7 integrated over the 1-mag bin at ``mv``, its mass limits
    from the dwarf sequence interpolated in log mass (closed form of the power law)."""
    seq_mv, _, seq_m = L.load_dwarf_sequence()
    m_bright, m_faint = (10.0 ** np.interp(mv + d, seq_mv, np.log10(seq_m)) for d in (-0.5, 0.5))
    return 0.016 / 3.7 * (m_faint ** -3.7 - m_bright ** -3.7)


def test_subgiants_are_what_wielen_allen_holds_beyond_bovys_main_sequence():
    mv, phi = L.subgiant_lf()
    assert mv.tolist() == [2.0, 3.0, 4.0]
    expected = [w - _bovy_ms(m) for w, m in zip(WIELEN_ALLEN_MV234, mv)]
    assert phi == pytest.approx(expected, rel=1e-9)
    assert np.all(phi > 0)


def test_the_components_share_out_exactly_the_local_subgiants():
    # the components present at the Sun add up to the local function, subgiants included; they
    # go where the giants go (the thin disc's giant-only companions, the thick disc, the halo),
    # in the giants' proportions, and the thin disc's dwarf components do not change
    local = [c for c in P.COMPONENTS if c.law != "bulge"]
    with_, without = (L.build_luminosity_table(local, subgiants=s) for s in (True, False))
    added = with_.total() - without.total()
    assert added.sum() == pytest.approx(L.subgiant_lf()[1].sum(), rel=1e-9)
    dwarfs = np.array([c.lf_part == "dwarfs" for c in local])
    assert np.array_equal(with_.cdf[dwarfs], without.cdf[dwarfs])
    assert np.all(added[~dwarfs] > 0)
    # each component's giants: its stars brighter than M_G = -0.5, all of them giants (the
    # brightest dwarf bin starts at M_V = 1, and no old population keeps its 2 Msun dwarfs)
    giants = np.array([np.interp(-0.5, without.mg, row) for row in without.cdf])
    assert added[~dwarfs] / added.sum() == pytest.approx(giants[~dwarfs] / giants[~dwarfs].sum(), rel=1e-6)


def test_subgiants_bring_the_g6_7_stars_at_mg_1_to_4_to_hipparcos():
    # Hipparcos 2 at G = 6-7 (complete): without subgiants the model holds 0.76-0.83 of its stars
    # at M' = 1-4 in every band, with them (Arenou dust) 0.99-1.06 (docs/galaxy_model.md)
    def mid_ratio(model):
        t = hp.absolute_magnitude_comparison(model, n_draw=40_000)
        t = t[(t.g_min == 6.0) & (t.mprime_lo >= 1.0) & (t.mprime_hi <= 4.0)]
        s = t.groupby("b_lo")[["n_model", "n_hip"]].sum()
        return (s.n_model / s.n_hip).to_numpy()

    old = dict(PARAMS_R03_5, extinction_model="arenou1992")
    assert np.all(mid_ratio(GalaxyModel(old, subgiants=False)) < 0.88)
    assert np.all(np.abs(mid_ratio(GalaxyModel(old, subgiants=True)) - 1.0) < 0.10)


def test_subgiants_must_be_a_boolean():
    from mcsweep.errors import UserInputError

    with pytest.raises(UserInputError, match="subgiants"):
        GalaxyModel(subgiants="yes")
