"""Barycentric position of the observer (Gaia near the Sun-Earth L2 point).

L2 model adopted here: Gaia sits on the line from the Sun through the Earth-Moon
barycentre (EMB), 1.01 times as far from the Sun as the EMB. L2 lies about 1.5e6 km
(0.01 au) beyond the Earth (de Bruijne 2012, Ap&SS 341, 31, Sect. 2); the real Lissajous
orbit around L2 (amplitude ~ 3e5 km, i.e. a 2e-3 au offset) is ignored: for a star at
1 kpc it shifts the parallax displacement by < 2 microarcsec and it is invisible in
the paper's statistics.

The Sun and EMB come from astropy's built-in ephemeris (ERFA ``epv00``), so no
download is needed. They are evaluated once on a regular grid and interpolated with
cubic splines; every star and every transit then reads the same tabulation instead of
calling the ephemeris again. The grid's values ship with the package
(``scanning/data/observer_table.npz``, written by ``python -m mcsweep.scanning.ephemeris``
from the same astropy call): evaluating ``epv00`` at its 26 000 epochs costs 1.3 s of
every run's start, reading the table milliseconds, and the splines are built from the
same numbers either way (tests/scanning compares the table with astropy).
"""

from __future__ import annotations

import sys
from functools import lru_cache

import numpy as np

from ..errors import UserInputError

__all__ = [
    "TABLE_FILE",
    "table_path",
    "compute_table",
    "table_epochs",
    "L2_DISTANCE_FACTOR",
    "TABLE_START_JD_TCB",
    "TABLE_END_JD_TCB",
    "gaia_position_au",
    "sun_position_au",
    "observer_position_au",
]

#: Gaia's heliocentric distance in units of the EMB's heliocentric distance (see module notes).
L2_DISTANCE_FACTOR = 1.01

# Tabulation span (TCB Julian dates): 2013-01-01 to 2031-01-01 covers launch, the
# nominal and the extended missions. Step 0.25 d: the cubic-spline error on the EMB
# orbit is then ~1e-10 au, far below what parallax factors need (1e-4 au = 1 muas at 1 kpc).
TABLE_START_JD_TCB = 2456293.5
TABLE_END_JD_TCB = 2462867.5
_STEP_DAYS = 0.25


#: The shipped tabulation (module notes).
TABLE_FILE = "observer_table.npz"


def table_epochs() -> np.ndarray:
    """The tabulation's epochs, TCB Julian dates."""
    return np.arange(TABLE_START_JD_TCB, TABLE_END_JD_TCB + _STEP_DAYS, _STEP_DAYS)


def compute_table(jd) -> tuple[np.ndarray, np.ndarray]:
    """(Gaia, Sun) barycentric positions [au], shape (n, 3), at the TCB Julian dates ``jd``,
    from astropy's built-in ephemeris and the L2 model (module notes)."""
    # astropy.coordinates only here: reading the shipped table needs none of it (0.2 s of
    # every process's start, the sweep's workers included).
    from astropy import units as u
    from astropy.coordinates import get_body_barycentric, solar_system_ephemeris
    from astropy.time import Time

    t = Time(np.asarray(jd, dtype=float), format="jd", scale="tcb")
    with solar_system_ephemeris.set("builtin"):
        sun = get_body_barycentric("sun", t).xyz.to_value(u.au).T
        emb = get_body_barycentric("earth-moon-barycenter", t).xyz.to_value(u.au).T
    return sun + L2_DISTANCE_FACTOR * (emb - sun), sun


def table_path():
    """The shipped tabulation inside the installed package."""
    from importlib.resources import files

    return files("mcsweep") / "scanning" / "data" / TABLE_FILE


@lru_cache(maxsize=1)
def _splines():
    from scipy.interpolate import CubicSpline  # 0.3 s of imports, for the processes that search transits

    jd = table_epochs()
    try:
        with table_path().open("rb") as f:
            table = np.load(f)
            gaia, sun = table["gaia_au"], table["sun_au"]
    except (FileNotFoundError, OSError, KeyError):  # a source tree without the table: compute it
        gaia, sun = compute_table(jd)
    if gaia.shape != (jd.size, 3):
        gaia, sun = compute_table(jd)
    return CubicSpline(jd, gaia, axis=0), CubicSpline(jd, sun, axis=0)


def _as_tcb_jd(t) -> np.ndarray:
    # An astropy Time exists only if astropy.time was imported: no import needed to test for one.
    time_module = sys.modules.get("astropy.time")
    if time_module is not None and isinstance(t, time_module.Time):
        jd = np.asarray(t.tcb.jd, dtype=float)
    else:
        jd = np.asarray(t, dtype=float)
    if jd.size and (np.nanmin(jd) < TABLE_START_JD_TCB or np.nanmax(jd) > TABLE_END_JD_TCB):
        raise UserInputError(
            f"epoch JD(TCB) {np.nanmin(jd):.1f}..{np.nanmax(jd):.1f} is outside the observer "
            f"ephemeris table; accepted: {TABLE_START_JD_TCB}..{TABLE_END_JD_TCB} (2013-2031)"
        )
    return jd


def gaia_position_au(t) -> np.ndarray:
    """Barycentric (BCRS, ICRS axes) position of Gaia in au.

    Parameters
    ----------
    t : astropy.time.Time or array_like
        Epochs; plain numbers are Julian dates in TCB.

    Returns
    -------
    ndarray, shape ``t.shape + (3,)``
        Barycentric position of Gaia, au (L2 model of the module notes).

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.scanning import gaia_position_au
    >>> r = gaia_position_au(2457400.5)  # TCB Julian date
    >>> round(float(np.linalg.norm(r)), 3)  # au from the barycentre  # doctest: +FLOAT_CMP
    0.993
    """
    jd = _as_tcb_jd(t)
    return _splines()[0](jd)


def sun_position_au(t) -> np.ndarray:
    """Barycentric position of the Sun in au (same conventions as :func:`gaia_position_au`)."""
    jd = _as_tcb_jd(t)
    return _splines()[1](jd)


def observer_position_au(transits) -> np.ndarray:
    """Gaia's BCRS position at each transit.

    Parameters
    ----------
    transits : pandas.DataFrame
        A table of :func:`mcsweep.scanning.find_transits`.

    Returns
    -------
    ndarray, shape (n, 3)
        Barycentric position, au (ICRS axes): the table's observer columns, or, for
        compact output, the same tabulation (:func:`gaia_position_au`) at ``tcb_jd``.

    Examples
    --------
    >>> from mcsweep.scanning import find_transits
    >>> tr = find_transits([150.0], [20.0], '2015-01-01T00:00:00',
    ...                   '2015-07-01T00:00:00')
    >>> from mcsweep.scanning import observer_position_au
    >>> observer_position_au(tr).shape
    (4, 3)
    """
    if "obs_x_au" in transits:
        return transits[["obs_x_au", "obs_y_au", "obs_z_au"]].to_numpy(float)
    return gaia_position_au(transits["tcb_jd"].to_numpy(float))


def main() -> None:
    """Write the shipped tabulation (``python -m mcsweep.scanning.ephemeris``)."""
    from pathlib import Path

    gaia, sun = compute_table(table_epochs())
    out = Path(__file__).resolve().parent / "data" / TABLE_FILE
    out.parent.mkdir(exist_ok=True)
    np.savez_compressed(out, gaia_au=gaia, sun_au=sun)
    print(f"{out}: {gaia.shape[0]} epochs")


if __name__ == "__main__":
    main()
