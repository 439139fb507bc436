"""Prior.from_run of a colour / colour_mean sweep: per-bin widths (Eq. 14 with the bin's
coefficients), NaN colours -> the colour-blind prior, the interpolated means, the proper
motion rotated to ICRS, and the maps of such a prior."""

import numpy as np
import pandas as pd
import pytest
from astropy import units as u
from astropy.coordinates import SkyCoord
from astropy.io import fits

from mcsweep.errors import UserInputError
from mcsweep.prior import Prior
from mcsweep.prior.maps import list_prior_maps, pixel_centres, prior_maps_bytes, read_prior_maps
from mcsweep.galactic import pm_icrs_from_galactic

#: Same formula through different code paths (a subset of stars vs all of them).
RTOL_PATHS = 1e-13
#: Closed form typed out here vs the package (different operation order).
RTOL_CLOSED_FORM = 1e-12
#: At the sweep's own directions and G bin centres the interpolation returns the cell's
#: value: the bilinear weights are 1 and 0 there, so only rounding remains (mas).
ATOL_AT_NODES = 1e-12
#: The proper-motion rotation (astropy's matrix applied with numpy) vs SkyCoord's own
#: transformation: rounding of the rotation, ~1e-15 relative, on values of ~10 mas/yr.
ATOL_PM_MASYR = 1e-11


def closed_form(l_deg, b_deg, g, c):
    """Eq. 14 with the coefficients c of Eqs. 15-17, typed out."""
    s0 = c["s0"][0] + c["s0"][1] * g + c["s0"][2] * g**2
    s1 = c["s1"][0] + c["s1"][1] * g + c["s1"][2] * g**2 + c["s1"][3] * g**3
    s2 = c["s2"][0] + c["s2"][1] * g
    lr, br = np.radians(l_deg), np.radians(b_deg)
    return 10 ** (s0 + s1 * np.abs(np.sin(br)) + s2 * np.cos(br) * np.cos(lr))


def _stars(n=400, seed=7):
    rng = np.random.default_rng(seed)
    return (rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n))), rng.uniform(6.5, 11.5, n))


def test_nan_colours_equal_the_colour_blind_prior(colour_mean_run, synth):
    prior = Prior.from_run(colour_mean_run)
    assert prior.has_colour and prior.has_mean
    l_deg, b_deg, g = _stars()
    blind = prior.sigma_parallax_mas(l_deg, b_deg, g)
    np.testing.assert_allclose(blind, closed_form(l_deg, b_deg, g, synth.BLIND), rtol=RTOL_CLOSED_FORM)
    nan = np.full(l_deg.size, np.nan)
    np.testing.assert_array_equal(prior.sigma_parallax_mas(l_deg, b_deg, g, bp_rp=nan), blind)
    np.testing.assert_array_equal(prior.mean_parallax_mas(l_deg, b_deg, g, bp_rp=nan),
                                  prior.mean_parallax_mas(l_deg, b_deg, g))
    for a, b in zip(prior.mean_pm_masyr(l_deg, b_deg, g, bp_rp=nan), prior.mean_pm_masyr(l_deg, b_deg, g)):
        np.testing.assert_array_equal(a, b)
    # mixed: the NaN rows still get the colour-blind prior
    mixed = np.where(np.arange(l_deg.size) % 3 == 0, np.nan, 1.0)
    got = prior.sigma_parallax_mas(l_deg, b_deg, g, bp_rp=mixed)
    np.testing.assert_allclose(got[::3], blind[::3], rtol=RTOL_PATHS, atol=0)
    assert (prior.colour_bin_label(mixed)[::3] == "colour_blind").all()
    # Quantity API, scalar NaN broadcast, and never an error
    c = SkyCoord(l=l_deg * u.deg, b=b_deg * u.deg, frame="galactic")
    np.testing.assert_allclose(prior.sigma_pm(c, G=g, bp_rp=np.nan).to_value(u.mas / u.yr), 10 * blind,
                               rtol=RTOL_PATHS)


def test_each_bin_uses_its_own_coefficients(colour_run, synth):
    prior = Prior.from_run(colour_run)
    assert prior.has_colour and not prior.has_mean
    l_deg, b_deg, g = _stars()
    # a colour in each bin, at the inner edges (half-open bins) and beyond the outer edges
    cases = [(-3.0, 0), (-1.0, 0), (0.3, 0), (0.56, 1), (1.0, 1), (1.23, 2), (2.5, 2), (9.0, 2)]
    for colour, k in cases:
        got = prior.sigma_parallax(l_deg * u.deg, b_deg * u.deg, G=g, bp_rp=colour * u.mag).to_value(u.mas)
        np.testing.assert_allclose(got, closed_form(l_deg, b_deg, g, synth.PER_BIN[k]), rtol=RTOL_CLOSED_FORM)
        assert prior.colour_bin(colour) == k
    assert list(prior.colour.labels) == ["-1..0.56", "0.56..1.23", "1.23..6"]
    # one call with a colour per star, broadcast against the positions
    colours = np.array([c for c, _ in cases])
    bins = np.array([k for _, k in cases])
    got = prior.sigma_parallax_mas(l_deg[:, None], b_deg[:, None], g[:, None], bp_rp=colours[None, :])
    assert got.shape == (l_deg.size, colours.size)
    for j, k in enumerate(bins):
        np.testing.assert_allclose(got[:, j], closed_form(l_deg, b_deg, g, synth.PER_BIN[k]), rtol=RTOL_CLOSED_FORM)
    n_p = prior.normal_matrix(l_deg, b_deg, G=g, bp_rp=1.0, factor=2.0)
    np.testing.assert_allclose(n_p[:, 2, 2], 1 / (2 * closed_form(l_deg, b_deg, g, synth.PER_BIN[1])) ** 2,
                               rtol=RTOL_CLOSED_FORM)
    # no mean: centred on zero
    assert not prior.mean_parallax(l_deg, b_deg, G=g, bp_rp=1.0).value.any()
    pmra, pmdec = prior.mean_pm(l_deg, b_deg, G=g)
    assert pmra.unit == u.mas / u.yr and not pmra.value.any() and not pmdec.value.any()
    with pytest.raises(UserInputError, match="bp_rp"):
        prior.sigma_parallax_mas(0.0, 0.0, 10.0, bp_rp=["red"])


def test_paper_and_plain_priors_ignore_colour_and_are_zero_centred(tmp_path, synth):
    paper = Prior.paper()
    assert not paper.has_colour and not paper.has_mean
    l_deg, b_deg, g = _stars()
    np.testing.assert_array_equal(paper.sigma_parallax_mas(l_deg, b_deg, g, bp_rp=np.full(l_deg.size, 2.0)),
                                  paper.sigma_parallax_mas(l_deg, b_deg, g))
    assert paper.mean_parallax(10.0, 20.0, G=12.0).value == 0.0
    assert paper.mean_parallax_mas(l_deg, b_deg, g, bp_rp=1.0).shape == l_deg.shape
    plain_cfg = synth.write_run(tmp_path / "plain", colour=False, mean=False)
    assert plain_cfg["prior_model"]["colour_edges"] == []
    plain = Prior.from_run(tmp_path / "plain")
    assert not plain.has_colour and not plain.has_mean
    np.testing.assert_allclose(plain.sigma_parallax_mas(l_deg, b_deg, g, bp_rp=0.2),
                               closed_form(l_deg, b_deg, g, synth.BLIND), rtol=RTOL_CLOSED_FORM)


def test_means_exact_at_the_sweep_cells(colour_mean_run, synth):
    prior = Prior.from_run(colour_mean_run)
    sky = {"kind": "healpix", "nside": 2, "order": "nested", "frame": "galactic"}
    l_deg, b_deg = synth.sky_directions_gal(sky)
    for slot, colour in enumerate([np.nan, -2.0, 1.0, 4.0]):
        for g in (7.0, 9.0, 11.0):  # G bin centres
            exp = synth.mean_field(l_deg, b_deg, g, slot)
            np.testing.assert_allclose(prior.mean_parallax_mas(l_deg, b_deg, g, bp_rp=colour), exp[0],
                                       rtol=0, atol=ATOL_AT_NODES)
            pmra, pmdec = prior.mean_pm_masyr(l_deg, b_deg, g, bp_rp=colour)
            ref = pm_icrs_from_galactic(l_deg, b_deg, exp[1], exp[2])
            np.testing.assert_allclose(pmra, ref[0], rtol=0, atol=ATOL_AT_NODES)
            np.testing.assert_allclose(pmdec, ref[1], rtol=0, atol=ATOL_AT_NODES)
    # G: linear between bin centres (the field is linear in G), constant outside
    mid = prior.mean_parallax_mas(l_deg, b_deg, 8.3)
    np.testing.assert_allclose(mid, synth.mean_field(l_deg, b_deg, 8.3, 0)[0], rtol=0, atol=ATOL_AT_NODES)
    for outside, edge in ((3.0, 7.0), (21.0, 11.0)):
        np.testing.assert_array_equal(prior.mean_parallax_mas(l_deg, b_deg, outside),
                                      prior.mean_parallax_mas(l_deg, b_deg, edge))


@pytest.mark.parametrize("nside,order,frame", [(4, "ring", "icrs"), (4, "nested", "galactic")])
def test_means_interpolate_a_smooth_field(tmp_path, nside, order, frame, synth):
    """Bilinear on the HEALPix grid: a field linear in the unit vector is reproduced to a
    fraction of its change over one pixel."""
    sky = {"kind": "healpix", "nside": nside, "order": order, "frame": frame}
    synth.write_run(tmp_path / "r", colour=False, sky=sky)
    prior = Prior.from_run(tmp_path / "r")
    l_deg, b_deg, _ = _stars(n=20000, seed=3)
    g = 9.0
    got = prior.mean_parallax_mas(l_deg, b_deg, g)
    # |grad f| <= |A| x scale(G); pixel size sqrt(4 pi / npix) rad: the error stays below half
    # the change of f over one pixel (measured: 0.11 mas at nside 4, 0.05 at nside 8).
    tol = 0.5 * np.linalg.norm(synth.A_PLX) * (1 + 0.1 * (12 - g)) * np.sqrt(4 * np.pi / (12 * nside**2))
    err = np.abs(got - synth.mean_field(l_deg, b_deg, g, 0)[0])
    assert err.max() < tol, (err.max(), tol)


def test_list_sky_uses_the_nearest_direction(tmp_path, synth):
    dirs = [[0.0, 0.0], [90.0, 30.0], [200.0, -60.0]]
    synth.write_run(tmp_path / "r", colour=False, sky={"kind": "list", "frame": "icrs", "directions": dirs})
    prior = Prior.from_run(tmp_path / "r")
    c = SkyCoord(ra=[1.0, 91.0, 199.0] * u.deg, dec=[1.0, 29.0, -61.0] * u.deg).galactic
    nodes = SkyCoord(ra=[0.0, 90.0, 200.0] * u.deg, dec=[0.0, 30.0, -60.0] * u.deg).galactic
    np.testing.assert_allclose(prior.mean_parallax_mas(c.l.deg, c.b.deg, 9.0),
                               synth.mean_field(nodes.l.deg, nodes.b.deg, 9.0, 0)[0], rtol=0, atol=ATOL_AT_NODES)


def test_pm_rotation_against_astropy():
    rng = np.random.default_rng(11)
    n = 2000
    l_deg, b_deg = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-0.999, 0.999, n)))
    pml, pmb = rng.normal(0, 10, n), rng.normal(0, 10, n)
    ra_pm, dec_pm = pm_icrs_from_galactic(l_deg, b_deg, pml, pmb)
    c = SkyCoord(l=l_deg * u.deg, b=b_deg * u.deg, pm_l_cosb=pml * u.mas / u.yr, pm_b=pmb * u.mas / u.yr,
                 frame="galactic").icrs
    np.testing.assert_allclose(ra_pm, c.pm_ra_cosdec.to_value(u.mas / u.yr), rtol=0, atol=ATOL_PM_MASYR)
    np.testing.assert_allclose(dec_pm, c.pm_dec.to_value(u.mas / u.yr), rtol=0, atol=ATOL_PM_MASYR)


def test_nan_cells_fall_back_and_bad_runs_are_refused(tmp_path, synth):
    # row 0: colour-blind cell of direction 0, G bin 0; row 1: its first colour cell
    synth.write_run(tmp_path / "nan", nan_cells=(1,))
    prior = Prior.from_run(tmp_path / "nan")
    assert prior.means.n_filled == 1
    sky = {"kind": "healpix", "nside": 2, "order": "nested", "frame": "galactic"}
    l_deg, b_deg = (v[:1] for v in synth.sky_directions_gal(sky))
    blind = prior.mean_parallax_mas(l_deg, b_deg, 7.0)[0]
    assert np.isfinite(blind) and prior.mean_parallax_mas(l_deg, b_deg, 7.0, bp_rp=0.0)[0] == blind
    synth.write_run(tmp_path / "blind_nan", nan_cells=(0,))  # a colour-blind cell without a mean
    with pytest.raises(UserInputError, match="colour-blind cell"):
        Prior.from_run(tmp_path / "blind_nan")
    synth.write_run(tmp_path / "nocolour", mean=False)
    (tmp_path / "nocolour" / "colour_coefficients.csv").unlink()
    with pytest.raises(UserInputError, match="colour_coefficients.csv"):
        Prior.from_run(tmp_path / "nocolour")
    synth.write_run(tmp_path / "short")
    p = tmp_path / "short" / "prior_means.csv"
    p.write_text("\n".join(p.read_text().splitlines()[:-3]) + "\n")
    assert Prior.from_run(tmp_path / "short").means.n_filled == 3  # the last cell's colour rows
    synth.write_run(tmp_path / "edges")
    import json
    prov = json.loads((tmp_path / "edges" / "provenance.json").read_text())
    prov["config"]["prior_model"]["colour_edges"] = [-1.0, 0.5, 1.23, 6.0]
    (tmp_path / "edges" / "provenance.json").write_text(json.dumps(prov))
    with pytest.raises(UserInputError, match="colour bin"):
        Prior.from_run(tmp_path / "edges")


def test_maps_of_colour_and_mean_round_trip(colour_mean_run, tmp_path, synth):
    prior = Prior.from_run(colour_mean_run)
    g_values = [7.0, 9.0, 11.0]
    path = tmp_path / "prior_maps.fits"
    path.write_bytes(prior_maps_bytes(prior, g_values, nside=4))
    l_deg, b_deg = pixel_centres(4)
    listed = {m["name"]: m for m in list_prior_maps(path)}
    k = len(synth.COLOUR_EDGES) - 1
    assert len(listed) == 1 + k + 3 * (1 + k)
    with fits.open(path) as hdul:
        assert [h.name for h in hdul[:2]] == ["PRIMARY", "SIGMA_F90"]
        assert hdul["SIGMA_F90_C2"].header["BPRPMIN"] == 0.56 and hdul["SIGMA_F90_C2"].header["NSIDE"] == 4
    for name, m in listed.items():
        nside, g, maps = read_prior_maps(path, name)
        assert nside == 4 and list(g) == g_values and maps.shape == (3, l_deg.size)
        colour = np.nan if np.isnan(m["bp_rp_min"]) else 0.5 * (m["bp_rp_min"] + m["bp_rp_max"])
        for i, gv in enumerate(g_values):
            if m["quantity"] == "SIGMA_F90":
                exp = prior.sigma_parallax_mas(l_deg, b_deg, gv, bp_rp=np.full(l_deg.size, colour))
            elif m["quantity"] == "MEAN_PARALLAX":
                exp = prior.mean_parallax_mas(l_deg, b_deg, gv, bp_rp=colour)
            else:
                exp = prior.mean_pm_masyr(l_deg, b_deg, gv, bp_rp=colour)[m["quantity"] == "MEAN_PMDEC"]
            np.testing.assert_allclose(maps[i], exp, rtol=RTOL_PATHS, atol=1e-14)
    nside, g, maps = read_prior_maps(path)  # default: the colour-blind sigma_F90 as before
    np.testing.assert_array_equal(maps[1], prior.sigma_parallax_mas(l_deg, b_deg, 9.0))
    with pytest.raises(UserInputError, match="SIGMA_F90_C9"):
        read_prior_maps(path, "SIGMA_F90_C9")
    # a plain prior's file has no extra HDU
    plain = tmp_path / "plain.fits"
    plain.write_bytes(prior_maps_bytes(Prior.paper(), g_values, nside=4))
    assert [m["name"] for m in list_prior_maps(plain)] == ["SIGMA_F90"]


def test_undetermined_bins_and_fit_ranges(colour_run, synth):
    """A bin without a fit gets the colour-blind prior; a bin's polynomials hold over the G
    range of the cells that determined them (g_fit_min, g_fit_max), the edge value beyond."""
    import pandas as pd

    path = colour_run / "colour_coefficients.csv"
    table = pd.read_csv(path)
    last = table["bp_rp_min"] == synth.COLOUR_EDGES[2]
    table.loc[last, "fitted"] = np.nan
    table["g_fit_min"], table["g_fit_max"] = 6.0, 12.0
    middle = table["bp_rp_min"] == synth.COLOUR_EDGES[1]
    table.loc[middle, ["g_fit_min", "g_fit_max"]] = (8.0, 10.0)
    table.to_csv(path, index=False)
    prior = Prior.from_run(colour_run)
    l_deg, b_deg, g = _stars()
    np.testing.assert_allclose(prior.sigma_parallax_mas(l_deg, b_deg, g, bp_rp=3.0),
                               prior.sigma_parallax_mas(l_deg, b_deg, g), rtol=RTOL_PATHS)
    assert prior.colour_bin_label(3.0) == "colour_blind" and prior.colour_bin(3.0) == -1
    for gq, g_eval in ((6.5, 8.0), (9.0, 9.0), (11.5, 10.0), (15.0, 10.0)):
        np.testing.assert_allclose(prior.sigma_parallax_mas(l_deg, b_deg, gq, bp_rp=1.0),
                                   closed_form(l_deg, b_deg, g_eval, synth.PER_BIN[1]), rtol=RTOL_CLOSED_FORM)
    # a bin fitted over the whole range keeps the prior's bright rule (extrapolation)
    np.testing.assert_allclose(prior.sigma_parallax_mas(l_deg, b_deg, 4.0, bp_rp=0.0),
                               closed_form(l_deg, b_deg, 4.0, synth.PER_BIN[0]), rtol=RTOL_CLOSED_FORM)


def test_g_bin_terms_take_over_from_the_polynomials(colour_run, synth):
    # colour_terms.csv (Eq. 14 per colour bin and G bin): at a G bin's centre the prior is Eq. 14
    # with that bin's terms, between centres the terms are interpolated, a bin without rows keeps
    # its polynomials.
    edges = synth.COLOUR_EDGES
    g_centres = [7.0, 9.0, 11.0]
    rows = [(lo, hi, g - 1.0, g + 1.0, g, 0.5 - 0.05 * g + 0.1 * k, 0.1 * k, -0.02)
            for k, (lo, hi) in enumerate(zip(edges, edges[1:])) if k < 2 for g in g_centres]
    pd.DataFrame(rows, columns=["bp_rp_min", "bp_rp_max", "g_min", "g_max", "g", "s0", "s1", "s2"]) \
        .to_csv(colour_run / "colour_terms.csv", index=False)
    prior = Prior.from_run(colour_run)
    l_deg, b_deg = np.array([10.0, 250.0]), np.array([5.0, -60.0])
    for k, colour in ((0, 0.0), (1, 1.0)):
        for g in g_centres:
            s0, s1, s2 = 0.5 - 0.05 * g + 0.1 * k, 0.1 * k, -0.02
            want = 10 ** (s0 + s1 * np.abs(np.sin(np.radians(b_deg))) + s2 * np.cos(np.radians(b_deg))
                          * np.cos(np.radians(l_deg)))
            np.testing.assert_allclose(prior.sigma_parallax_mas(l_deg, b_deg, g, bp_rp=colour), want,
                                       rtol=RTOL_CLOSED_FORM)
    mid = prior.sigma_parallax_mas(l_deg, b_deg, 8.0, bp_rp=0.0)
    ends = [prior.sigma_parallax_mas(l_deg, b_deg, g, bp_rp=0.0) for g in (7.0, 9.0)]
    np.testing.assert_allclose(np.log10(mid), np.mean(np.log10(ends), axis=0), rtol=RTOL_CLOSED_FORM)
    last = prior.sigma_parallax_mas(l_deg, b_deg, 12.0, bp_rp=3.0)  # no rows: the polynomials
    np.testing.assert_allclose(last, closed_form(l_deg, b_deg, 12.0, synth.PER_BIN[2]), rtol=RTOL_CLOSED_FORM)


def test_a_bin_without_its_own_width_is_flagged_in_the_maps(colour_run, synth):
    import io

    from mcsweep.prior.run_record import COLOUR_COEFFICIENTS_FILE

    path = colour_run / COLOUR_COEFFICIENTS_FILE
    table = pd.read_csv(path)
    table.loc[table["bp_rp_min"] == synth.COLOUR_EDGES[0], "fitted"] = np.nan  # the bluest bin undetermined
    table.to_csv(path, index=False)
    prior = Prior.from_run(colour_run)
    hdus = fits.open(io.BytesIO(prior_maps_bytes(prior, [10.0], nside=1)))
    flags = [h.header["CBINFIT"] for h in hdus if h.name.startswith("SIGMA_F90_C")]
    assert flags == [False] + [True] * (len(synth.COLOUR_EDGES) - 2)
    # ... and its map is the colour-blind prior, which its stars get.
    np.testing.assert_array_equal(hdus["SIGMA_F90_C1"].data.field(0), hdus["SIGMA_F90"].data.field(0))
