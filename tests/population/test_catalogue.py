"""CatalogueSource: formats, column conventions, units, selections and one-line errors."""

import numpy as np
import pandas as pd
import pytest
from astropy import units as u
from astropy.coordinates import SkyCoord
from astropy.table import Table

from mcsweep.errors import UserInputError
from mcsweep.population import COLUMNS, CatalogueSource

N_STARS = 400
COORD_TOL_DEG = 1e-8


def _stars(rng, n=N_STARS):
    ra = rng.uniform(150, 165, n)
    dec = rng.uniform(-8, 8, n)
    plx = rng.uniform(0.1, 5.0, n)
    return dict(ra=ra, dec=dec, parallax=plx, pmra=rng.normal(0, 10, n),
                pmdec=rng.normal(0, 10, n), phot_g_mean_mag=rng.uniform(10, 20, n))


def _gaia_csv(tmp_path, rng, **overrides):
    d = _stars(rng)
    d.update(overrides)
    path = tmp_path / "stars.csv"
    pd.DataFrame(d).to_csv(path, index=False)
    return path, d


def test_gaia_source_csv_round_trip(tmp_path, rng):
    path, d = _gaia_csv(tmp_path, rng)
    src = CatalogueSource(path)
    t = src.table
    assert list(t.columns) == list(COLUMNS) and len(t) == N_STARS
    gal = SkyCoord(ra=d["ra"] * u.deg, dec=d["dec"] * u.deg).galactic
    assert np.allclose(t.l, gal.l.deg, atol=COORD_TOL_DEG) and np.allclose(t.b, gal.b.deg, atol=COORD_TOL_DEG)
    assert np.allclose(t.distance_pc, 1000 / d["parallax"])
    assert (t.population == "catalogue").all()


def test_cone_and_magnitude_selection_matches_brute_force(tmp_path, rng):
    path, d = _gaia_csv(tmp_path, rng)
    src = CatalogueSource(path)
    l0, b0, r = 245.7, 46.5, 3.0
    c0 = SkyCoord(l=l0 * u.deg, b=b0 * u.deg, frame="galactic")
    sep = SkyCoord(ra=d["ra"] * u.deg, dec=d["dec"] * u.deg).separation(c0).deg
    want = (sep <= r) & (d["phot_g_mean_mag"] >= 12) & (d["phot_g_mean_mag"] < 19)
    df = src.sample_cone(l0, b0, r, 12, 19, np.random.default_rng(0))
    assert len(df) == want.sum() == src.expected_count(l0, b0, r, 12, 19)
    assert np.allclose(np.sort(df.ra), np.sort(d["ra"][want]))
    capped = src.sample_cone(l0, b0, r, 12, 19, np.random.default_rng(0), max_stars=5)
    assert len(capped) == 5 and capped.attrs["n_in_cone"] == want.sum()
    assert set(capped.ra).issubset(set(df.ra))
    assert len(src.sample_sky(10, 20, np.random.default_rng(0))) == N_STARS


def test_gums_fits_with_units_and_population(tmp_path, rng):
    d = _stars(rng)
    t = Table()
    t["ra"], t["dec"] = d["ra"] * u.deg, d["dec"] * u.deg
    t["barycentric_distance"] = (1.0 / d["parallax"]) * u.kpc      # kpc: must be converted
    t["pmra"], t["pmdec"] = d["pmra"] * u.mas / u.yr, d["pmdec"] * u.mas / u.yr
    t["mag_g"] = d["phot_g_mean_mag"] * u.mag
    t["population"] = np.where(np.arange(N_STARS) % 2, "thin", "thick")
    path = tmp_path / "gums.fits"
    t.write(path)
    src = CatalogueSource(path)
    assert np.allclose(src.table.parallax, d["parallax"])
    assert np.allclose(src.table.distance_pc, 1000 / d["parallax"])
    assert set(src.table.population.cat.categories) == {"thin", "thick"}


@pytest.mark.parametrize("fmt, writer", [
    ("parquet", lambda df, p: df.to_parquet(p)),
    ("votable", lambda df, p: Table.from_pandas(df).write(p, format="votable")),
    ("ecsv", lambda df, p: Table.from_pandas(df).write(p, format="ascii.ecsv")),
])
def test_other_formats(tmp_path, rng, fmt, writer):
    df = pd.DataFrame(_stars(rng))
    path = tmp_path / f"stars.{ {'votable': 'vot'}.get(fmt, fmt) }"
    writer(df, path)
    src = CatalogueSource(path)
    assert np.allclose(src.table.pmra, df.pmra)


def test_column_mapping_and_units_override(tmp_path, rng):
    d = _stars(rng)
    df = pd.DataFrame({"RAdeg": d["ra"], "DEdeg": d["dec"], "plx_arcsec": d["parallax"] / 1000,
                       "pmra": d["pmra"], "pmdec": d["pmdec"], "Gmag": d["phot_g_mean_mag"]})
    path = tmp_path / "vizier.csv"
    df.to_csv(path, index=False)
    src = CatalogueSource(path, columns={"ra": "RAdeg", "dec": "DEdeg", "parallax": "plx_arcsec",
                                         "phot_g_mean_mag": "Gmag"}, units={"parallax": "arcsec"})
    assert np.allclose(src.table.parallax, d["parallax"])


def _one_line_error(path, match, **kwargs):
    with pytest.raises(UserInputError) as err:
        CatalogueSource(path, **kwargs)
    msg = str(err.value)
    assert "\n" not in msg and path.name in msg
    assert match in msg, msg
    return msg


def test_missing_column(tmp_path, rng):
    d = _stars(rng)
    del d["pmdec"]
    path = tmp_path / "nopm.csv"
    pd.DataFrame(d).to_csv(path, index=False)
    msg = _one_line_error(path, "'pmdec'")
    assert "mas/yr" in msg


def test_nan_values_error_or_drop(tmp_path, rng):
    d = _stars(rng)
    d["parallax"][:3] = np.nan
    path = tmp_path / "nan.csv"
    pd.DataFrame(d).to_csv(path, index=False)
    msg = _one_line_error(path, "column 'parallax' has 3 NaN values")
    assert "expected finite numbers in mas" in msg
    src = CatalogueSource(path, on_missing="drop")
    assert len(src.table) == N_STARS - 3 and src.n_dropped == 3


def test_non_numeric_values(tmp_path, rng):
    d = _stars(rng)
    df = pd.DataFrame(d)
    df["pmra"] = df["pmra"].astype(object)
    df.loc[5, "pmra"] = "fast"
    path = tmp_path / "text.csv"
    df.to_csv(path, index=False)
    _one_line_error(path, "column 'pmra' has 1 non-numeric values (first: 'fast')")


def test_wrong_unit_and_out_of_range(tmp_path, rng):
    d = _stars(rng)
    t = Table({k: v for k, v in d.items()})
    t["parallax"].unit = u.km
    path = tmp_path / "unit.fits"
    t.write(path)
    _one_line_error(path, "column 'parallax' has unit 'km'; expected mas")
    path2, _ = _gaia_csv(tmp_path, rng, dec=np.full(N_STARS, 120.0))
    _one_line_error(path2, "column 'dec' has 400 values outside -90..90 deg")


def test_bad_file_and_empty_selection(tmp_path, rng):
    _one_line_error(tmp_path / "absent.csv", "file not found")
    bad = tmp_path / "broken.fits"
    bad.write_text("not a fits file")
    _one_line_error(bad, "cannot be read as fits")
    _one_line_error(tmp_path / "stars.xyz", "cannot tell the format")
    path, _ = _gaia_csv(tmp_path, rng)
    src = CatalogueSource(path)
    with pytest.raises(UserInputError) as err:
        src.sample_cone(0.0, -80.0, 1.0, 10, 20, np.random.default_rng(0))
    msg = str(err.value)
    assert "stars.csv" in msg and "phot_g_mean_mag" in msg and "expected at least one" in msg
    assert src.expected_count(0.0, -80.0, 1.0, 10, 20) == 0.0
