"""HEALPix maps of the prior in a FITS file that healpy and astropy-healpix read.

``prior_maps.fits`` holds

* HDU 1 ``SIGMA_F90``: one column per G value (the sweep's bin centres), each a full-sky
  HEALPix map of sigma_F90 [mas] in galactic coordinates, RING ordering, one row per
  pixel (``INDXSCHM = 'IMPLICIT'``), with the keywords of the HEALPix FITS convention
  (Gorski et al. 2005, ApJ 622, 759, and the HEALPix "FITS format" notes that healpy's
  ``read_map`` follows): ``PIXTYPE, ORDERING, NSIDE, COORDSYS, INDXSCHM, OBJECT,
  FIRSTPIX, LASTPIX``, plus ``TUNITn = 'mas'`` and ``GMAGn`` (the G at which column n
  is evaluated). The prior's origin, G range, P and R are in the header too.
* HDU 2 ``CELLS``: the per-cell values behind the fit (simulated sigma_F90, the fitted
  and the paper's formula at each cell), with units.

A prior with a colour axis (:attr:`~mcsweep.prior.Prior.has_colour`) adds, after these, one HDU per
BP-RP bin k = 1..K, ``SIGMA_F90_C<k>``, laid out as ``SIGMA_F90`` (same columns, G and
HEALPix keywords) with the bin in ``BPRPMIN``, ``BPRPMAX`` [mag], ``CBINLAB``
(``'lo..hi'``) and ``CBINFIT`` (F: the bin has no width of its own and the map is the
colour-blind prior its stars get); ``SIGMA_F90`` itself stays the colour-blind prior. A mean-centred prior
(:attr:`~mcsweep.prior.Prior.has_mean`) adds the prior's centre, ``MEAN_PARALLAX`` [mas], ``MEAN_PMRA``
and ``MEAN_PMDEC`` [mas/yr, ICRS components, pmra = mu_alpha*] (colour-blind), and with a
colour axis the same per bin (``MEAN_PARALLAX_C<k>`` ...). Every map HDU carries
``QUANTITY`` (``SIGMA_F90``, ``MEAN_PARALLAX``, ``MEAN_PMRA`` or ``MEAN_PMDEC``);
:func:`list_prior_maps` lists them and :func:`read_prior_maps` reads any of them. For a
prior without colour or mean the file is as before (HDUs 0-2 only).

Pixel values are :meth:`mcsweep.prior.Prior.sigma_parallax_mas` at the pixel centres
(astropy-healpix ``HEALPix(nside, order='ring', frame=Galactic())``).
"""

from __future__ import annotations

import io
from typing import TYPE_CHECKING

import numpy as np

from ..errors import UserInputError

if TYPE_CHECKING:  # astropy.io.fits on first use: the config schema imports MAX_NSIDE from here
    from astropy.io import fits

    from .model import Prior

__all__ = ["MAPS_FILE", "DEFAULT_NSIDE", "MAX_NSIDE", "MAP_QUANTITIES", "check_nside", "pixel_centres",
           "map_column_name", "map_hdu_name", "prior_maps_hdulist", "prior_maps_bytes", "read_prior_maps",
           "list_prior_maps"]

MAPS_FILE = "prior_maps.fits"
#: Default resolution: 3072 pixels of ~3.7 deg, finer than the sweep's 48 directions
#: and the smooth Eq. 14 can show.
DEFAULT_NSIDE = 16
#: Largest accepted nside (786 432 pixels x 8 bytes x G bins stays below ~100 MB).
MAX_NSIDE = 256
#: The mapped quantities: HDU name prefix -> (unit, what).
MAP_QUANTITIES = {
    "SIGMA_F90": ("mas", "sigma_F90 of the parallax prior"),
    "MEAN_PARALLAX": ("mas", "centre of the parallax prior"),
    "MEAN_PMRA": ("mas/yr", "centre of the pmra* prior (ICRS)"),
    "MEAN_PMDEC": ("mas/yr", "centre of the pmdec prior (ICRS)"),
}


def check_nside(nside) -> int:
    """Return ``nside`` as an int, or raise UserInputError unless a power of two <= MAX_NSIDE."""
    ok = isinstance(nside, (int, np.integer)) and not isinstance(nside, bool) and 1 <= nside <= MAX_NSIDE \
        and (int(nside) & (int(nside) - 1)) == 0
    if not ok:
        raise UserInputError(f"nside={nside!r} is not accepted; expected a power of two from 1 to {MAX_NSIDE}")
    return int(nside)


def pixel_centres(nside: int) -> tuple[np.ndarray, np.ndarray]:
    """Galactic (l, b) in degrees of every RING pixel centre, pixel order."""
    from astropy.coordinates import Galactic
    from astropy_healpix import HEALPix

    hp = HEALPix(nside=check_nside(nside), order="ring", frame=Galactic())
    lon, lat = hp.healpix_to_lonlat(np.arange(hp.npix))
    return lon.deg, lat.deg


def map_column_name(g: float, quantity: str = "SIGMA_F90") -> str:
    """Column name of the map at G = g, e.g. ``SIGMA_F90_G14_50``."""
    return f"{quantity}_G{g:05.2f}".replace(".", "_")


def map_hdu_name(quantity: str, colour_bin: int | None = None) -> str:
    """HDU name of a map: ``quantity`` (colour-blind) or ``quantity_C<k>`` for BP-RP bin k = 1..K."""
    return quantity if colour_bin is None else f"{quantity}_C{colour_bin}"


def _healpix_keywords(h, nside: int, npix: int) -> None:
    for key, value, comment in (
        ("PIXTYPE", "HEALPIX", "HEALPix pixelisation"),
        ("ORDERING", "RING", "pixel ordering scheme"),
        ("NSIDE", nside, "HEALPix resolution parameter"),
        ("COORDSYS", "G", "galactic coordinates"),
        ("INDXSCHM", "IMPLICIT", "row i holds pixel i"),
        ("OBJECT", "FULLSKY", "full-sky maps"),
        ("FIRSTPIX", 0, "first pixel number"),
        ("LASTPIX", npix - 1, "last pixel number"),
    ):
        h[key] = (value, comment)


def _extra_map_hdus(prior: Prior, g_values, nside: int, l_deg, b_deg) -> list:
    """The colour-bin and mean HDUs (module notes), in order; [] for a plain prior."""
    from astropy.io import fits

    npix = l_deg.size
    bins = [(None, np.nan)]
    if prior.has_colour:
        edges = prior.colour.edges
        # a colour inside each bin selects it (ColourBins.index)
        bins += [(k + 1, 0.5 * (lo + hi)) for k, (lo, hi) in enumerate(zip(edges, edges[1:]))]
    wanted = [("SIGMA_F90", k, c) for k, c in bins if k is not None]
    if prior.has_mean:
        wanted += [(q, k, c) for k, c in bins for q in ("MEAN_PARALLAX", "MEAN_PMRA", "MEAN_PMDEC")]
    hdus = []
    for quantity, k, colour in wanted:
        unit, what = MAP_QUANTITIES[quantity]
        columns = []
        for g in g_values:
            bp_rp = np.full(npix, colour)
            if quantity == "SIGMA_F90":
                values = prior.sigma_parallax_mas(l_deg, b_deg, g, bp_rp)
            elif quantity == "MEAN_PARALLAX":
                values = prior.mean_parallax_mas(l_deg, b_deg, g, bp_rp)
            else:
                values = prior.mean_pm_masyr(l_deg, b_deg, g, bp_rp)[quantity == "MEAN_PMDEC"]
            columns.append(fits.Column(name=map_column_name(g, quantity), format="D", unit=unit, array=values))
        hdu = fits.BinTableHDU.from_columns(columns, name=map_hdu_name(quantity, k))
        h = hdu.header
        _healpix_keywords(h, nside, npix)
        h["BUNIT"] = (unit, what)
        h["QUANTITY"] = (quantity, "mapped quantity")
        if k is None:
            h["CBINLAB"] = ("colour_blind", "prior of stars of unknown BP-RP")
        else:
            lo, hi = prior.colour.edges[k - 1], prior.colour.edges[k]
            h["CBIN"] = (k, "BP-RP bin number (1 = bluest)")
            h["BPRPMIN"] = (lo, "[mag] lower edge (first bin: all bluer too)")
            h["BPRPMAX"] = (hi, "[mag] upper edge (last bin: all redder too)")
            h["CBINLAB"] = (prior.colour.labels[k - 1], "BP-RP bin label")
            # A bin without a width of its own maps the colour-blind prior (what its stars get).
            h["CBINFIT"] = (bool(prior.colour_bin(colour) >= 0), "T: the bin's own prior; F: colour-blind")
        h["PRIORSRC"] = (str(prior.origin)[-40:], "origin of the prior")
        for i, g in enumerate(g_values, start=1):
            h[f"GMAG{i}"] = (g, f"G magnitude of column {i}")
        hdus.append(hdu)
    return hdus


def prior_maps_hdulist(prior: Prior | None, g_values, *, nside: int = DEFAULT_NSIDE, cells=None) -> fits.HDUList:
    """FITS file of sigma_F90 maps (module notes).

    Parameters
    ----------
    prior : Prior or None
        The prior to map; None writes NaN maps (a sweep whose coefficients could not be
        fitted), flagged by ``FITTED = F`` in the header.
    g_values : sequence of float
        G of each map (a sweep's bin centres).
    nside : int, keyword-only
        HEALPix resolution (a power of two).
    cells : pandas.DataFrame, optional, keyword-only
        Per-cell table for HDU 2; columns ending in ``_deg`` and ``_mas`` get those units.

    Returns
    -------
    astropy.io.fits.HDUList
    """
    from astropy.io import fits

    g_values = [float(g) for g in g_values]
    if not g_values:
        raise UserInputError("no G values to map; expected at least one magnitude bin")
    nside = check_nside(nside)
    l_deg, b_deg = pixel_centres(nside)
    npix = l_deg.size
    columns = []
    for g in g_values:
        values = np.full(npix, np.nan) if prior is None else prior.sigma_parallax_mas(l_deg, b_deg, g)
        columns.append(fits.Column(name=map_column_name(g), format="D", unit="mas", array=values))
    maps = fits.BinTableHDU.from_columns(columns, name="SIGMA_F90")
    h = maps.header
    _healpix_keywords(h, nside, npix)
    for key, value, comment in (
        ("BUNIT", "mas", "sigma_F90 of the parallax prior"),
        ("FITTED", prior is not None, "F: coefficients not fitted (NaN maps)"),
        ("PRIORSRC", "none" if prior is None else str(prior.origin)[-40:], "origin of coefficients"),
        ("GMIN", None if prior is None else prior.g_min, "faint/bright rules apply outside GMIN-GMAX"),
        ("GMAX", None if prior is None else prior.g_max, "G > GMAX uses the value at GMAX"),
        ("CONFLEV", None if prior is None else prior.confidence, "confidence level P of sigma_F90"),
        ("RATIO_R", None if prior is None else prior.ratio_R, "sigma_mu / sigma_plx [1/yr] (Eq. 18)"),
        ("BRIGHT", None if prior is None else prior.bright, "treatment of G < GMIN"),
    ):
        h[key] = (value, comment)
    for i, g in enumerate(g_values, start=1):
        h[f"GMAG{i}"] = (g, f"G magnitude of column {i}")
    h.add_comment("sigma_F90 of Michalik et al. 2015 (A&A 583, A68) Eqs. 14-17 at the pixel centres")
    hdus = [fits.PrimaryHDU(), maps]
    if cells is not None:
        from astropy.table import Table

        t = Table.from_pandas(cells.reset_index(drop=True))
        for name in t.colnames:
            if name.endswith("_deg"):
                t[name].unit = "deg"
            elif name.endswith("_mas"):
                t[name].unit = "mas"
            if t[name].dtype.kind == "O":
                t[name] = t[name].astype(str)
        cells_hdu = fits.table_to_hdu(t)
        cells_hdu.name = "CELLS"
        hdus.append(cells_hdu)
    if prior is not None:
        hdus += _extra_map_hdus(prior, g_values, nside, l_deg, b_deg)
    return fits.HDUList(hdus)


def prior_maps_bytes(prior: Prior | None, g_values, *, nside: int = DEFAULT_NSIDE, cells=None) -> bytes:
    """:func:`prior_maps_hdulist` serialised, for an atomic write by the caller."""
    buf = io.BytesIO()
    prior_maps_hdulist(prior, g_values, nside=nside, cells=cells).writeto(buf)
    return buf.getvalue()


def read_prior_maps(path, name: str = "SIGMA_F90") -> tuple[int, np.ndarray, np.ndarray]:
    """Read one map of a ``prior_maps.fits`` (HEALPix, RING order, galactic frame).

    Parameters
    ----------
    path : str or path-like
        The file a sweep wrote.
    name : str
        The map HDU: ``SIGMA_F90`` (default, the colour-blind sigma_F90) or any other
        listed by :func:`list_prior_maps` (e.g. ``SIGMA_F90_C2``, ``MEAN_PMRA``).

    Returns
    -------
    nside : int
        HEALPix resolution.
    g_values : ndarray, shape (n_g,)
        G of each map column, mag.
    maps : ndarray, shape (n_g, npix)
        The values (unit in the HDU's header: mas or mas/yr).

    Examples
    --------
    These read a run's files; the lines are skipped when the examples run as
    tests (no run directory there).

    >>> from mcsweep.prior.maps import read_prior_maps
    >>> path = 'results/default/prior_maps.fits'
    >>> nside, g, maps = read_prior_maps(path)  # doctest: +SKIP
    >>> maps.shape  # (n_g, 12 nside^2)  # doctest: +SKIP
    """
    from astropy.io import fits

    with fits.open(path) as hdul:
        names = [hdu.name for hdu in hdul[1:] if hdu.header.get("PIXTYPE") == "HEALPIX"]
        if name not in names:
            raise UserInputError(f"{path}: has no map HDU {name!r}; expected one of {names}")
        h = hdul[name].header
        data = hdul[name].data
        n = h["TFIELDS"]
        g = np.array([h[f"GMAG{i}"] for i in range(1, n + 1)], dtype=float)
        maps = np.stack([np.asarray(data.field(i), dtype=float) for i in range(n)])
        return int(h["NSIDE"]), g, maps


def list_prior_maps(path) -> list[dict]:
    """The map HDUs of a ``prior_maps.fits``, in file order.

    Parameters
    ----------
    path : str or path-like
        The file a sweep wrote.

    Returns
    -------
    list of dict
        One per HDU, keys ``name`` (for :func:`read_prior_maps`), ``quantity`` (a key of
        ``MAP_QUANTITIES``), ``unit``, ``bp_rp_min``, ``bp_rp_max`` (mag; NaN for the
        colour-blind maps) and ``label`` (``'lo..hi'`` or ``'colour_blind'``).

    Examples
    --------
    These read a run's files; the lines are skipped when the examples run as
    tests (no run directory there).

    >>> from mcsweep.prior.maps import list_prior_maps
    >>> path = 'results/colour/prior_maps.fits'
    >>> [m['name'] for m in list_prior_maps(path)]  # doctest: +SKIP
    """
    from astropy.io import fits

    out = []
    with fits.open(path) as hdul:
        for hdu in hdul[1:]:
            h = hdu.header
            if h.get("PIXTYPE") != "HEALPIX":
                continue
            quantity = h.get("QUANTITY", "SIGMA_F90")
            out.append({"name": hdu.name, "quantity": quantity, "unit": MAP_QUANTITIES[quantity][0],
                        "bp_rp_min": float(h.get("BPRPMIN", np.nan)), "bp_rp_max": float(h.get("BPRPMAX", np.nan)),
                        "label": h.get("CBINLAB", "colour_blind")})
    return out
