"""prior_maps.fits: read back with astropy-healpix and astropy.io.fits only."""

import json

import numpy as np
import pandas as pd
import pytest
from astropy.coordinates import Galactic
from astropy.io import fits
from astropy_healpix import HEALPix

from mcsweep.errors import UserInputError
from mcsweep.prior import Prior
from mcsweep.prior.maps import check_nside, map_column_name, prior_maps_bytes
from mcsweep.experiments.f90_sweep.fit import fit_all, prior_maps_for_run

#: The map and Prior.from_run evaluate the same formula at the same pixel centres, but
#: the map went through a FITS file: float64 round-trips exactly, so only array-vs-scalar
#: numpy kernels can differ (last bits).
RTOL_PATHS = 1e-13
#: Against the closed form typed out in the test (different operation order).
RTOL_CLOSED_FORM = 1e-12


def _synthetic_run(run_dir, nside=8):
    """A run directory whose cells follow Eqs. 14-17 with known coefficients, plus noise."""
    rng = np.random.default_rng(3)
    coef = {"s0": (2.1, -0.25, 0.0065), "s1": (0.1, -0.05, 0.013, -0.0005), "s2": (0.03, -0.006)}
    truth = Prior(coef, 6.0, 11.0, 0.9, 10.0, origin="truth")
    rows = []
    for g0 in range(6, 11):
        l_deg = rng.uniform(0, 360, 30)
        b_deg = np.degrees(np.arcsin(rng.uniform(-1, 1, 30)))
        s = truth.sigma_parallax_mas(l_deg, b_deg, g0 + 0.5) * 10 ** rng.normal(0, 0.02, 30)
        rows.append(pd.DataFrame(dict(cell_id=[f"c{g0}_{i}" for i in range(30)], l_deg=l_deg, b_deg=b_deg,
                                      g_min=float(g0), g_max=g0 + 1.0, n_stars=300, radius_deg=1.0,
                                      sigma_f90_mas=s, f90_flag="ok")))
    fit = fit_all(pd.concat(rows, ignore_index=True))
    run_dir.mkdir()
    (run_dir / "coefficients.csv").write_text(fit.coefficients.to_csv(index=False))
    cfg = {"magnitudes": {"edges": list(range(6, 12))}, "confidence": 0.9, "ratio_R": 10.0,
           "prior_maps": {"nside": nside}}
    (run_dir / "provenance.json").write_text(json.dumps({"kind": "f90_sweep", "config": cfg}))
    return fit, cfg


def test_maps_read_with_astropy_healpix_equal_prior_from_run(tmp_path):
    run = tmp_path / "run"
    fit, cfg = _synthetic_run(run, nside=8)
    (run / "prior_maps.fits").write_bytes(prior_maps_for_run(run, fit, nside=cfg["prior_maps"]["nside"]))
    prior = Prior.from_run(run)
    with fits.open(run / "prior_maps.fits") as hdul:
        h = hdul[1].header
        assert (h["PIXTYPE"], h["ORDERING"], h["COORDSYS"], h["INDXSCHM"], h["NSIDE"]) == \
            ("HEALPIX", "RING", "G", "IMPLICIT", 8)
        assert h["LASTPIX"] == 12 * 8**2 - 1 and len(hdul[1].data) == 12 * 8**2
        hp = HEALPix(nside=h["NSIDE"], order=h["ORDERING"].lower(), frame=Galactic())
        lon, lat = hp.healpix_to_lonlat(np.arange(hp.npix))
        g_values = [h[f"GMAG{i}"] for i in range(1, h["TFIELDS"] + 1)]
        assert g_values == [6.5, 7.5, 8.5, 9.5, 10.5]
        for i, g in enumerate(g_values, start=1):
            assert h[f"TUNIT{i}"] == "mas" and h[f"TTYPE{i}"] == map_column_name(g)
            values = hdul[1].data.field(i - 1)
            expected = prior.sigma_parallax(lon.deg, lat.deg, G=g).value
            np.testing.assert_allclose(values, expected, rtol=RTOL_PATHS, atol=0)
            # and the closed form with the fitted coefficients, read from the CSV by name
            c = pd.read_csv(run / "coefficients.csv").set_index("term")["fitted"]
            lr, br = lon.rad, lat.rad
            log_s = (c["s0_c0"] + c["s0_c1"] * g + c["s0_c2"] * g**2) \
                + (c["s1_c0"] + c["s1_c1"] * g + c["s1_c2"] * g**2 + c["s1_c3"] * g**3) * np.abs(np.sin(br)) \
                + (c["s2_c0"] + c["s2_c1"] * g) * np.cos(br) * np.cos(lr)
            np.testing.assert_allclose(values, 10**log_s, rtol=RTOL_CLOSED_FORM, atol=0)
        cells = hdul["CELLS"].data
        assert len(cells) == 150 and hdul["CELLS"].columns["sigma_f90_mas"].unit == "mas"
        np.testing.assert_array_equal(cells["sigma_f90_mas"], fit.compared["sigma_f90_mas"].to_numpy())


def test_unfitted_run_gets_nan_maps_flagged(tmp_path):
    hdul = fits.HDUList.fromstring(prior_maps_bytes(None, [15.5], nside=2))
    assert hdul[1].header["FITTED"] is False
    assert np.isnan(hdul[1].data.field(0)).all() and len(hdul[1].data) == 48


def test_nside_must_be_a_power_of_two():
    assert check_nside(16) == 16
    for bad in (0, 3, 12, 512, 2.0, True):
        with pytest.raises(UserInputError, match="nside"):
            check_nside(bad)
