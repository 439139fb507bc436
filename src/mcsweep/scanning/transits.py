"""Field-of-view transits of many directions under a scanning law.

A star at unit vector u transits a field of view when its azimuth in the scan plane,
``phi = atan2(u . y, u . x)`` in the SRS, passes the FoV azimuth (+Gamma/2 for the
preceding FoV, -Gamma/2 for the following one; phi decreases as Gaia spins) while its
across-scan offset ``zeta = asin(u . z)`` is within the FoV's acceptance. Because
``|zeta|`` < 0.41 deg, a star is scanned only while the precessing spin axis z keeps it
within ~0.4 deg of the scan great circle, i.e. for a few hours around each zero of
``f(t) = u . z(t)`` (about 60 per star in 5 years).

The search (vectorised over stars in chunks, no loop over stars or transits) is
described in ``mcsweep.scanning.search``; this module validates the inputs, draws
the dead time and the dilution key, splits the stars into blocks (one joblib task
each when ``n_jobs != 1``) and assembles the output table.

Transit times are TCB Julian dates at Gaia. The observer's barycentric position at
each transit comes from :func:`mcsweep.scanning.gaia_position_au` (one
spline evaluation per transit, no ephemeris call per star).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import pandas as pd

from ..errors import UserInputError
from .attitude import attitude_for
from .ephemeris import TABLE_END_JD_TCB, TABLE_START_JD_TCB, observer_position_au
from .frames import ICRS_TO_ECLIPTIC, local_north_east, unit_vector
from .law import ScanningLaw
from .search import build_nodes, run_block
from .timeline import draw_dead_time, dilution_key
from .timescale import tcb_jd
from ..renamed_names import old_names, renamed_keyword

__all__ = ["find_transits", "observer_position_au", "TRANSIT_COLUMNS", "DEFAULT_DEAD_TIME_OUTAGE_DAYS"]

#: Output columns, in order (see docs/architecture.md, section "scanning").
TRANSIT_COLUMNS = ("source_index", "tcb_jd", "fov", "scan_angle_deg", "ac_offset_deg", "group",
                   "obs_x_au", "obs_y_au", "obs_z_au")
#: Default length of one dead-time block [day] (about one spin; the paper gives no gap lengths).
DEFAULT_DEAD_TIME_OUTAGE_DAYS = 0.25
# Target number of float32 entries of F per chunk (16 MB).
_F_ENTRIES_PER_CHUNK = 4_000_000
# Stars per block (one joblib task when n_jobs != 1); ~30 MB of results for 5 years.
_STARS_PER_BLOCK = 10_000


@lru_cache(maxsize=1)
def _malloc_trim():
    try:
        import ctypes

        return ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):  # not glibc: nothing to do
        return None


def _release_free_heap() -> None:
    """Give freed heap memory back to the OS (glibc ``malloc_trim``; a no-op elsewhere).

    Blocks smaller than glibc's dynamic mmap threshold (up to 32 MB) live on the heap,
    and freeing them does not lower the process's memory: without this, turning N bytes
    of blocks into N bytes of columns peaks at ~2N instead of N plus one block.
    """
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


def _assemble(blocks: list) -> dict:
    """Columns from the blocks' chunk results, each freed once copied (peak ~ total + 1 block)."""
    first = blocks[0][0]
    total = sum(part["tcb_jd"].shape[0] for blk in blocks for part in blk)
    cols = {k: np.empty(total, dtype=v.dtype) for k, v in first.items()}
    pos = 0
    while blocks:
        blk = blocks.pop(0)
        while blk:
            part = blk.pop(0)
            size = part["tcb_jd"].shape[0]
            for k in cols:
                cols[k][pos:pos + size] = part[k]
            pos += size
            del part
        _release_free_heap()
    return cols


def find_transits(ra_deg, dec_deg, start, end, *, law: ScanningLaw | None = None,
                  dead_time_fraction: float = 0.0, dilution: float = 0.0, rng=None,
                  dead_time_outage_days: float | None = None, n_jobs: int = 1,
                  compact: bool = False, dead_time_block_days: float | None = None) -> pd.DataFrame:
    """All field-of-view transits of the given directions between ``start`` and ``end``.

    Parameters
    ----------
    ra_deg, dec_deg : array_like, shape (n,)
        ICRS right ascension and declination of the directions [deg].
    start, end : astropy.time.Time, str or float
        Interval ``[start, end)``; a string is an ISO date in TCB, a float a TCB Julian
        date. Must lie within 2013-2031 (the observer-ephemeris table).
    law : ScanningLaw, keyword-only
        Scanning law; default the flown law (``ScanningLaw()``), a sequence of segments
        valid 2014-07-25T10:30 - 2025-01-15 (TCB) and extrapolated outside; the gaps
        between segments (2017-01-27 - 02-08) have no transits.
    dead_time_fraction : float, keyword-only
        Fraction of the time line lost, in [0, 1) (the paper's 20 % is 0.2); drawn as
        outages of ``dead_time_outage_days`` (see ``mcsweep.scanning.timeline``).
    dilution : float, keyword-only
        Probability in [0, 1] that each FoV transit is removed (the paper's 95 % is 0.95).
    rng : numpy.random.Generator, int or None, keyword-only
        Randomness for dead time and dilution (normalised with ``np.random.default_rng``);
        unused when both are 0.
    dead_time_outage_days : float, keyword-only
        Length of one dead-time outage [day]; default ``DEFAULT_DEAD_TIME_OUTAGE_DAYS`` (0.25).
    n_jobs : int, keyword-only
        Processes for joblib (1 = in process; -1 = all cores). Results do not depend on it.
    compact : bool, keyword-only
        Store ``source_index`` as int32, ``group`` as int16 and the angles as float32
        (precision 1e-5 deg), and leave out the observer columns (a function of
        ``tcb_jd``: :func:`observer_position_au`), 23 instead of 65 bytes per transit,
        to hold ~10^8 transits in memory; ``tcb_jd`` stays float64.
    dead_time_block_days : float, keyword-only
        Deprecated name of ``dead_time_outage_days``.

    Returns
    -------
    pandas.DataFrame
        One row per FoV transit, sorted by (``source_index``, ``tcb_jd``), with columns
        ``source_index`` (index into the inputs), ``tcb_jd`` (transit time at Gaia, TCB
        Julian date), ``fov`` ('P' or 'F', categorical), ``scan_angle_deg`` (position
        angle psi of the scan direction, 0 = local north, 90 = local east, in [0, 360)),
        ``ac_offset_deg`` (zeta), ``group`` (0-based distinct-transit number per source,
        Table 1's "#" minus one, counted among the transits that survive dead time and
        dilution; see ``mcsweep.scanning.groups``) and
        ``obs_x_au, obs_y_au, obs_z_au`` (Gaia's BCRS position, ICRS axes; not in
        compact output).
        ``df.attrs`` holds the law, the interval, the options and ``extrapolated`` (the
        sentence of ``ScanningLaw.extrapolation_note``, or None).

    Raises
    ------
    mcsweep.errors.UserInputError
        On malformed directions, an empty or out-of-range interval, or fractions
        outside their range.

    Examples
    --------
    >>> from mcsweep.scanning import find_transits
    >>> tr = find_transits([150.0], [20.0], '2015-01-01T00:00:00',
    ...                   '2015-07-01T00:00:00')
    >>> len(tr), list(tr.columns[:4])
    (4, ['source_index', 'tcb_jd', 'fov', 'scan_angle_deg'])
    """
    law = ScanningLaw() if law is None else law
    if not isinstance(law, ScanningLaw):
        raise UserInputError(f"law={law!r} is not accepted; expected a ScanningLaw "
                             "(use ScanningLaw.from_config for a config mapping)")
    ra = np.atleast_1d(np.asarray(ra_deg, dtype=float))
    dec = np.atleast_1d(np.asarray(dec_deg, dtype=float))
    if ra.ndim != 1 or ra.shape != dec.shape:
        raise UserInputError(f"ra_deg/dec_deg of shapes {ra.shape}/{dec.shape} are not accepted; "
                             "expected two 1-D arrays of equal length")
    if not (np.all(np.isfinite(ra)) and np.all(np.isfinite(dec)) and np.all(np.abs(dec) <= 90.0)):
        raise UserInputError("ra_deg/dec_deg are not accepted; expected finite values with |dec| <= 90 deg")
    start_jd, end_jd = tcb_jd(start, "start"), tcb_jd(end, "end")
    if not end_jd > start_jd:
        raise UserInputError(f"interval {start}..{end} is not accepted; expected end after start")
    if start_jd < TABLE_START_JD_TCB + 1.0 or end_jd > TABLE_END_JD_TCB - 1.0:
        raise UserInputError(f"interval JD(TCB) {start_jd:.1f}..{end_jd:.1f} is not accepted; "
                             f"expected within {TABLE_START_JD_TCB + 1}..{TABLE_END_JD_TCB - 1} (2013-2031)")
    if not 0.0 <= dead_time_fraction < 1.0:
        raise UserInputError(f"dead_time_fraction={dead_time_fraction!r} is not accepted; expected [0, 1)")
    if not 0.0 <= dilution <= 1.0:
        raise UserInputError(f"dilution={dilution!r} is not accepted; expected a probability in [0, 1]")
    dead_time_outage_days = renamed_keyword("find_transits", "dead_time_block_days", dead_time_block_days,
                                            "dead_time_outage_days", dead_time_outage_days,
                                            default=DEFAULT_DEAD_TIME_OUTAGE_DAYS)
    if not dead_time_outage_days > 0.0:
        raise UserInputError(f"dead_time_outage_days={dead_time_outage_days!r} is not accepted; expected > 0")

    rng = np.random.default_rng(rng)
    dead = None
    if dead_time_fraction > 0.0:
        dead = draw_dead_time(start_jd, end_jd, dead_time_fraction, outage_days=dead_time_outage_days, rng=rng)
    dil_key = dilution_key(rng) if dilution > 0.0 else None

    att = attitude_for(law)
    nodes = build_nodes(att, start_jd, end_jd)
    attrs = {"dead_time_fraction": dead_time_fraction, "dilution": dilution,
             "dead_time_outage_days": dead_time_outage_days}
    if nodes is None:  # the interval lies in a gap between the law's segments: no transits
        return _to_frame(_empty_columns(compact), law, start_jd, end_jd, attrs=attrs)
    u_ecl = unit_vector(ra, dec) @ ICRS_TO_ECLIPTIC.T
    north, east = local_north_east(ra, dec)
    north_ecl, east_ecl = north @ ICRS_TO_ECLIPTIC.T, east @ ICRS_TO_ECLIPTIC.T
    opts = {"dead": dead, "dilution_key": dil_key, "dilution": dilution, "compact": compact}
    chunk = max(64, _F_ENTRIES_PER_CHUNK // (nodes.n_intervals + 1))
    n = ra.size
    n_blocks = max(1, math.ceil(n / _STARS_PER_BLOCK))
    if n_jobs != 1 and n > chunk:
        n_blocks = max(2, n_blocks)
    edges = np.linspace(0, n, n_blocks + 1).astype(np.int64)
    tasks = [(u_ecl[a:b], north_ecl[a:b], east_ecl[a:b], int(a), nodes, att, opts, chunk)
             for a, b in zip(edges[:-1], edges[1:]) if b > a]
    if n_blocks == 1 or n_jobs == 1:
        blocks = [run_block(*task) for task in tasks]
    else:
        from joblib import Parallel, delayed

        blocks = Parallel(n_jobs=n_jobs)(delayed(run_block)(*task) for task in tasks)
    cols = _assemble(blocks)
    return _to_frame(cols, law, start_jd, end_jd, attrs=attrs)


def _empty_columns(compact: bool) -> dict:
    """The column dict of :func:`mcsweep.scanning.search.chunk_transits` with no rows."""
    int_t, grp_t, flt_t = (np.int32, np.int16, np.float32) if compact else (np.int64, np.int64, np.float64)
    cols = {"source_index": np.empty(0, int_t), "tcb_jd": np.empty(0), "fov_code": np.empty(0, np.int8),
            "scan_angle_deg": np.empty(0, flt_t), "ac_offset_deg": np.empty(0, flt_t), "group": np.empty(0, grp_t)}
    if not compact:
        cols.update(obs_x_au=np.empty(0), obs_y_au=np.empty(0), obs_z_au=np.empty(0))
    return cols


def _to_frame(cols: dict, law: ScanningLaw, start_jd: float, end_jd: float, attrs: dict) -> pd.DataFrame:
    data = {}
    for key in TRANSIT_COLUMNS:
        if key.startswith("obs_") and key not in cols:
            continue  # compact output
        if key == "fov":
            data[key] = pd.Categorical.from_codes(cols.pop("fov_code"), categories=["P", "F"])
        else:
            data[key] = cols.pop(key)
    df = pd.DataFrame(data, copy=False)
    df.attrs.update({"scanning_law": law.name, "start_tcb_jd": start_jd, "end_tcb_jd": end_jd,
                     "extrapolated": law.extrapolation_note(start_jd, end_jd), **attrs})
    return df


#: A dead-time "block" was renamed an outage: a block is a group of stars (docs/architecture.md).
__getattr__ = old_names(__name__, {"DEFAULT_DEAD_TIME_BLOCK_DAYS": "DEFAULT_DEAD_TIME_OUTAGE_DAYS"})
