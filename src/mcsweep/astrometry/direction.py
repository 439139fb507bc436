"""A source's direction recovered from its along-scan parallax factors.

Some Gaia DR4 epoch-astrometry files (the vendored sample among them,
``mcsweep/data/epoch_astrometry``) carry no position of the source. Each field-of-view
transit, however, gives the AL parallax factor ``P_AL`` (``parallax_factor_al``), the scan
position angle theta (``scan_pos_angle``) and the time, and the parallax factor depends on
the source's direction ``u``:

    P_AL = -(b . p(u)) sin(theta) - (b . q(u)) cos(theta)

with ``b`` the observer's barycentric (BCRS) position in au and ``p``, ``q`` the unit
vectors towards local east and north at ``u`` (the normal triad; the parallax factor
of Lindegren et al. 2012, A&A 538, A78, Sect. 5.2, the AL row of Eq. 1 of Michalik et
al. 2015, A&A 583, A68, "the paper": :func:`mcsweep.astrometry.design_matrix`'s
parallax column, whose sign the files follow). theta is measured at ``u`` (0 = local
north, 90 deg = local east; AL direction ``(sin theta, cos theta)`` in (alpha*, delta)).

Method. With ``b(t)`` from the project's observer model
(:func:`mcsweep.scanning.gaia_position_au`), the direction is the nonlinear
least-squares fit of the modelled to the given ``P_AL`` over the two coordinates of ``u``,
unweighted (every transit's factor is exact):

1. grid search: the sum of squared residuals at every direction of a Fibonacci sphere of
   ``GRID_SIZE`` points (3.7 deg apart), vectorised over directions and transits (a
   quadratic form in the six components of ``(p, q)``, whose 6 x 6 matrix sums the
   transits once);
2. refinement with :func:`scipy.optimize.least_squares` from the best
   ``N_STARTS`` grid directions at least ``START_SEPARATION_DEG`` apart
   (other local minima, if any, are then not taken for the solution), in gnomonic
   offsets about each start, so the poles are no special case; the lowest minimum wins.

There is no exact two-fold ambiguity: at the antipode ``p`` changes sign and ``q`` does
not, so its factors are not ``-P_AL`` and the fit is poor there. Other local minima do
occur, but far worse than the solution (on the vendored sample: one near a pole with an
RMS of 0.09 against 9e-4 at the solution), hence the several starts.

Accuracy. The files' factors hold Gaia's real orbit, a Lissajous orbit about L2 of a few
1e-3 au amplitude with a period of ~180 days; the model here is L2 itself (1.01 x the
Sun-EMB vector), so the model's ``b`` is wrong by ~1e-3 au, slowly varying, and so are
the modelled factors. A change of direction by ``x`` rad changes ``P_AL`` by up to
``|b| x ~ x`` (``|b|`` ~ 1 au), and the orbit's offset, semi-annual like the scans' sampling
of each source, does not average out: the direction is biased by ~1e-3 rad, ~0.1 deg.
Measured: 0.02-0.2 deg on simulated scans whose factors hold a Lissajous-like offset of
Gaia's size (semi-amplitudes 0.9, 2.4, 1.2 x 1e-3 au; ``tests/astrometry/test_direction.py``),
and 0.07 and 0.10 deg for the two sample sources that are Hipparcos stars (HIP 983 and
114046). The residual RMS of ``P_AL`` at the solution is ~1e-3, the size of the orbit's
offset, not of the direction's error. A second, smaller cause: the time used is the
barycentric ``obs_time_tcb + obs_time_bary_corr`` (what
:func:`~mcsweep.astrometry.epoch_astrometry.ccd_observations` gives), not the time at
Gaia; the difference (< 500 s) moves Gaia by < 1e-4 au. With the model's own ``b``
(simulated data) the direction is recovered to rounding error (< 1e-12 deg). Enough to
place a source on the sky (its Galactic latitude, the prior's sigma_F90 at its
direction), not as astrometry.

``python -m mcsweep.astrometry.direction`` regenerates ``sample_sources.csv`` beside the
vendored sample (``main``): each source's recovered direction, its G (AGIS's
``gMag``) and the RMS of its parallax factors at that direction.
"""

from __future__ import annotations

from importlib import resources

import numpy as np

from ..errors import UserInputError
from ..scanning.ephemeris import gaia_position_au
from ..scanning.frames import tangent_triad

__all__ = [
    "GRID_SIZE",
    "N_STARTS",
    "START_SEPARATION_DEG",
    "MIN_TRANSITS",
    "parallax_factors_al",
    "direction_from_parallax_factors",
    "directions_of_sources",
    "sample_sources_table",
    "main",
]

#: Directions of the Fibonacci-sphere grid of the first search (mean spacing 3.7 deg).
GRID_SIZE = 3072
#: Grid directions from which the least-squares refinement starts.
N_STARTS = 4
#: Smallest separation between two starting directions [deg].
START_SEPARATION_DEG = 15.0
#: Fewest transits accepted (two unknowns; a third makes the residual meaningful).
MIN_TRANSITS = 3

# The vendored sample: package, folder, files.
_PACKAGE = "mcsweep"
_SAMPLE_DIR = ("data", "epoch_astrometry")
_EPOCH_FILE = "sample_epoch_astrometry.parquet"
_AGIS_FILE = "sample_agis_results.parquet"
_SOURCES_FILE = "sample_sources.csv"


def parallax_factors_al(ra_deg, dec_deg, scan_angle_deg, obs_au) -> np.ndarray:
    """AL parallax factors ``P_AL = -(b . p) sin(theta) - (b . q) cos(theta)`` (module notes).

    Parameters
    ----------
    ra_deg, dec_deg : array_like
        Direction of the source (ICRS) [deg]; broadcast against ``scan_angle_deg``.
    scan_angle_deg : array_like
        Scan position angle theta of each transit [deg] (0 = local north, 90 = local east).
    obs_au : array_like, shape ``scan_angle_deg.shape + (3,)``
        Observer's BCRS position at each transit [au].

    Returns
    -------
    ndarray
        ``P_AL`` [au per au of parallax, i.e. mas of AL displacement per mas of parallax],
        the parallax column of :func:`mcsweep.astrometry.design_matrix`.
    """
    p, q, _ = tangent_triad(ra_deg, dec_deg)
    b = np.asarray(obs_au, dtype=float)
    theta = np.radians(np.asarray(scan_angle_deg, dtype=float))
    return -(np.sum(b * p, axis=-1) * np.sin(theta) + np.sum(b * q, axis=-1) * np.cos(theta))


def _fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit vectors (Fibonacci lattice), shape (n, 3)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    lon = np.pi * (3.0 - np.sqrt(5.0)) * i
    rho = np.sqrt(1.0 - z * z)
    return np.stack([rho * np.cos(lon), rho * np.sin(lon), z], axis=-1)


def _ra_dec_deg(u) -> tuple[np.ndarray, np.ndarray]:
    """Right ascension in [0, 360) and declination [deg] of vectors ``u (..., 3)``."""
    u = np.asarray(u, dtype=float)
    ra = np.degrees(np.arctan2(u[..., 1], u[..., 0])) % 360.0
    dec = np.degrees(np.arctan2(u[..., 2], np.hypot(u[..., 0], u[..., 1])))
    return ra, dec


def _grid_cost(sin_t, cos_t, b, pfac, grid) -> np.ndarray:
    """Sum of squared residuals of ``P_AL`` at every grid direction, shape (n_grid,).

    The residual of transit i is ``P_i + m_i . x`` with ``m_i = (sin_i b_i, cos_i b_i)``
    and ``x = (p, q)`` of the direction, so the sum is ``c + 2 g . x + x' S x`` with the
    transit sums ``S = M'M`` (6 x 6), ``g = M'P`` and ``c = P'P``: one pass over the
    transits, then a few operations per grid direction.
    """
    m = np.concatenate([sin_t[:, None] * b, cos_t[:, None] * b], axis=1)  # (k, 6)
    s, g, c = m.T @ m, m.T @ pfac, pfac @ pfac
    ra, dec = _ra_dec_deg(grid)
    p, q, _ = tangent_triad(ra, dec)
    x = np.concatenate([p, q], axis=1)  # (n_grid, 6)
    return c + 2.0 * (x @ g) + np.einsum("ni,ij,nj->n", x, s, x)


def _starts(grid, cost, n_starts: int, min_sep_deg: float) -> list[np.ndarray]:
    """The best grid directions, each at least ``min_sep_deg`` from the ones before."""
    cos_min = np.cos(np.radians(min_sep_deg))
    chosen: list[np.ndarray] = []
    for idx in np.argsort(cost):
        u = grid[idx]
        if all(u @ v < cos_min for v in chosen):
            chosen.append(u)
            if len(chosen) == n_starts:
                break
    return chosen


def _refine(u0, scan_angle_deg, b, pfac):
    """Least-squares minimum near ``u0``: (unit vector, residuals)."""
    from scipy.optimize import least_squares

    ra0, dec0 = _ra_dec_deg(u0)
    p0, q0, r0 = tangent_triad(ra0, dec0)

    def direction(xy):
        u = r0 + xy[0] * p0 + xy[1] * q0  # gnomonic offsets [rad] about the start
        return u / np.linalg.norm(u)

    def residuals(xy):
        ra, dec = _ra_dec_deg(direction(xy))
        return parallax_factors_al(ra, dec, scan_angle_deg, b) - pfac

    fit = least_squares(residuals, np.zeros(2), method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return direction(fit.x), fit.fun


def _check_transits(tcb_jd, scan_angle_deg, parallax_factor_al):
    arrays = [np.asarray(a, dtype=float) for a in (tcb_jd, scan_angle_deg, parallax_factor_al)]
    shapes = {a.shape for a in arrays}
    if len(shapes) != 1 or arrays[0].ndim != 1:
        raise UserInputError(f"tcb_jd/scan_angle_deg/parallax_factor_al of shapes {[a.shape for a in arrays]} "
                             "are not accepted; expected three 1-D arrays of equal length (one source's transits)")
    if not all(np.isfinite(a).all() for a in arrays):
        raise UserInputError("tcb_jd/scan_angle_deg/parallax_factor_al hold non-finite values; expected finite "
                             "values for every transit")
    if arrays[0].size < MIN_TRANSITS:
        raise UserInputError(f"{arrays[0].size} transits are not enough to recover a direction; expected at "
                             f"least {MIN_TRANSITS}")
    return arrays


def direction_from_parallax_factors(tcb_jd, scan_angle_deg, parallax_factor_al) -> tuple[float, float, float]:
    """ICRS direction of one source from its transits' AL parallax factors (module notes).

    Parameters
    ----------
    tcb_jd : array_like, shape (k,)
        Time of each transit, TCB Julian date (the files' ``obs_time_tcb +
        obs_time_bary_corr``; the time at Gaia is as good), within the ephemeris table
        (2013-2031).
    scan_angle_deg : array_like, shape (k,)
        Scan position angle theta [deg] (0 = local north, 90 = local east).
    parallax_factor_al : array_like, shape (k,)
        The files' AL parallax factor of each transit [mas of AL displacement per mas of
        parallax].

    Returns
    -------
    ra_deg, dec_deg : float
        Right ascension in [0, 360) and declination of the source [deg]; ~0.1 deg at
        worst on real files (module notes: the L2 observer model), exact on factors made
        with :func:`mcsweep.scanning.gaia_position_au`.
    rms : float
        Root mean square of the residuals of ``P_AL`` at that direction (same unit);
        ~1e-3 on real files, the size of Gaia's orbit about L2 in au.

    Raises
    ------
    mcsweep.errors.UserInputError
        On arrays of different shapes, non-finite values, fewer than
        ``MIN_TRANSITS`` (3) transits or epochs outside the ephemeris table.

    Examples
    --------
    >>> from importlib.resources import files
    >>> data = files('mcsweep') / 'data' / 'epoch_astrometry'
    >>> from mcsweep.tables import read_table
    >>> from mcsweep.astrometry.epoch_astrometry import ccd_observations
    >>> table = read_table(data / 'sample_epoch_astrometry.parquet')
    >>> obs = ccd_observations(table)
    >>> from mcsweep.astrometry.direction import (
    ...     direction_from_parallax_factors)
    >>> one = obs.source_id == obs.source_id[0]
    >>> ra, dec, rms = direction_from_parallax_factors(
    ...     obs.tcb_jd[one], obs.scan_angle_deg[one],
    ...     obs.parallax_factor_al[one])
    >>> # deg; sample_sources.csv has 335.1979, 38.1801
    >>> round(ra, 1), round(dec, 1)  # doctest: +FLOAT_CMP
    (335.2, 38.2)
    """
    t, theta, pfac = _check_transits(tcb_jd, scan_angle_deg, parallax_factor_al)
    b = gaia_position_au(t)
    rad = np.radians(theta)
    grid = _fibonacci_sphere(GRID_SIZE)
    cost = _grid_cost(np.sin(rad), np.cos(rad), b, pfac, grid)
    best_u, best_ss = None, np.inf
    for u0 in _starts(grid, cost, N_STARTS, START_SEPARATION_DEG):
        u, res = _refine(u0, theta, b, pfac)
        ss = float(res @ res)
        if ss < best_ss:
            best_u, best_ss = u, ss
    ra, dec = _ra_dec_deg(best_u)
    return float(ra), float(dec), float(np.sqrt(best_ss / t.size))


def directions_of_sources(source_id, tcb_jd, scan_angle_deg, parallax_factor_al):
    """:func:`direction_from_parallax_factors` for every source of a table of transits.

    Parameters
    ----------
    source_id : array_like of int, shape (k,)
        Source of each transit (any order; one row per field-of-view transit).
    tcb_jd, scan_angle_deg, parallax_factor_al : array_like, shape (k,)
        As in :func:`direction_from_parallax_factors` (TCB Julian date, deg, mas/mas).

    Returns
    -------
    pandas.DataFrame
        One row per source, sorted by ``source_id`` (int64), with ``ra``, ``dec`` [deg]
        and ``parallax_factor_rms`` (RMS residual of ``P_AL`` at that direction).
        A loop over sources: for tens of sources, not a hot path.
    """
    import pandas as pd

    ids = np.asarray(source_id)
    t, theta, pfac = (np.asarray(a, dtype=float) for a in (tcb_jd, scan_angle_deg, parallax_factor_al))
    if ids.ndim != 1 or not (ids.shape == t.shape == theta.shape == pfac.shape):
        raise UserInputError(f"source_id/tcb_jd/scan_angle_deg/parallax_factor_al of shapes "
                             f"{[ids.shape, t.shape, theta.shape, pfac.shape]} are not accepted; expected four "
                             "1-D arrays of equal length")
    ids = ids.astype(np.int64)
    order = np.argsort(ids, kind="stable")
    unique, first = np.unique(ids[order], return_index=True)
    rows = []
    for sid, part in zip(unique, np.split(order, first[1:])):
        rows.append((sid, *direction_from_parallax_factors(t[part], theta[part], pfac[part])))
    df = pd.DataFrame(rows, columns=["source_id", "ra", "dec", "parallax_factor_rms"])
    return df.astype({"source_id": np.int64})


def sample_sources_table():
    """The table of ``sample_sources.csv``, recomputed from the vendored sample.

    Returns
    -------
    pandas.DataFrame
        ``source_id``, ``ra``, ``dec`` [deg], ``phot_g_mean_mag`` (AGIS's ``gMag``) and
        ``parallax_factor_rms_direction`` (RMS residual of ``P_AL`` at the direction),
        one row per source of ``sample_epoch_astrometry.parquet``, unrounded.
    """
    from ..tables import read_table
    from .epoch_astrometry import ccd_observations

    folder = resources.files(_PACKAGE).joinpath(*_SAMPLE_DIR)
    with resources.as_file(folder.joinpath(_EPOCH_FILE)) as path:
        obs = ccd_observations(read_table(path, what="epoch astrometry"))
    with resources.as_file(folder.joinpath(_AGIS_FILE)) as path:
        agis = read_table(path, what="AGIS results")
    # One row per transit (``transit`` numbers the file's rows): its first kept CCD in
    # time; the factor is per transit and the CCDs of one transit span ~40 s.
    _, first = np.unique(obs.transit, return_index=True)
    df = directions_of_sources(obs.source_id[first], obs.tcb_jd[first], obs.scan_angle_deg[first],
                               obs.parallax_factor_al[first])
    g = dict(zip(np.asarray(agis["sourceId"]).astype(np.int64), np.asarray(agis["gMag"], dtype=float)))
    df.insert(3, "phot_g_mean_mag", [g.get(int(s), np.nan) for s in df["source_id"]])
    return df.rename(columns={"parallax_factor_rms": "parallax_factor_rms_direction"})


def main() -> None:
    """Write ``sample_sources.csv`` beside the vendored sample (``python -m mcsweep.astrometry.direction``)."""
    df = sample_sources_table()
    out = df.assign(ra=df["ra"].round(4), dec=df["dec"].round(4),
                    phot_g_mean_mag=df["phot_g_mean_mag"].round(4),
                    parallax_factor_rms_direction=[float(f"{v:.3g}") for v in df["parallax_factor_rms_direction"]])
    header = (f"# Made by python -m mcsweep.astrometry.direction: ra, dec [deg, ICRS] recovered from the parallax "
              f"factors of {_EPOCH_FILE} (L2 observer model, ~0.1 deg), phot_g_mean_mag = gMag of {_AGIS_FILE}, "
              "parallax_factor_rms_direction = RMS residual of parallax_factor_al at that direction\n")
    folder = resources.files(_PACKAGE).joinpath(*_SAMPLE_DIR)
    with resources.as_file(folder) as directory:
        path = directory / _SOURCES_FILE
        with open(path, "w", encoding="utf-8", newline="") as fh:
            fh.write(header)
            out.to_csv(fh, index=False)
    print(f"wrote {path} ({len(out)} sources)")


if __name__ == "__main__":
    main()
