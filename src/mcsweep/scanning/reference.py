"""Straightforward reference for the transit search: every star tested at every time step.

The attitude is sampled on a fine regular time grid (default 20 s, i.e. 0.33 deg of
spin); at every step the azimuth ``phi`` and across-scan offset ``zeta`` of every star
are computed from the attitude *matrix*, and a transit is recorded where
``phi - FoV azimuth`` changes sign from positive to negative with ``zeta`` accepted.
Time and angles are linearly interpolated between the two steps.

It shares only the attitude (:class:`mcsweep.scanning.attitude.Attitude`) with the fast
search in :mod:`mcsweep.scanning.transits`, and is used to check it (tests) and as
the baseline of ``benchmarks/bench_transits.py``. Its cost is O(n_stars x n_steps):
fine for tens of stars, not for a catalogue.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .attitude import attitude_for
from .frames import ECLIPTIC_TO_ICRS, local_north_east, unit_vector
from .law import ScanningLaw

__all__ = ["reference_transits"]


def reference_transits(ra_deg, dec_deg, start_jd: float, end_jd: float, *,
                       law: ScanningLaw | None = None, step_s: float = 20.0,
                       block_steps: int = 20_000) -> pd.DataFrame:
    """Transits found by brute force on a time grid (no dead time, no dilution, no groups).

    Parameters
    ----------
    ra_deg, dec_deg : array_like, shape (n,)
        ICRS directions [deg].
    start_jd, end_jd : float
        Interval, TCB Julian dates [day].
    law : ScanningLaw, keyword-only
        Default the flown law.
    step_s : float, keyword-only
        Time step [s].
    block_steps : int, keyword-only
        Steps processed at once (memory ~ 9 x 8 x block_steps x (1 + n) bytes).

    Returns
    -------
    pandas.DataFrame
        Columns ``source_index, tcb_jd, fov, scan_angle_deg, ac_offset_deg``, sorted by
        (source_index, tcb_jd).
    """
    law = ScanningLaw() if law is None else law
    att = attitude_for(law)
    ra = np.atleast_1d(np.asarray(ra_deg, dtype=float))
    dec = np.atleast_1d(np.asarray(dec_deg, dtype=float))
    u_icrs = unit_vector(ra, dec)
    north, east = local_north_east(ra, dec)
    half = 0.5 * math.radians(law.basic_angle_deg)
    fovs = (("P", half, law.ac_limits_p_deg), ("F", -half, law.ac_limits_f_deg))
    step = step_s / 86400.0
    n_steps = int(math.ceil((end_jd - start_jd) / step)) + 1
    rows = []
    for b0 in range(0, n_steps - 1, block_steps):
        k = np.arange(b0, min(b0 + block_steps + 1, n_steps))
        t = start_jd + step * k
        # SRS axes in ICRS components: columns of E^T A.
        axes = np.einsum("ij,tjk->tik", ECLIPTIC_TO_ICRS, att.matrix(t))
        srs = np.einsum("tik,ni->tnk", axes, u_icrs)  # (steps, stars, 3)
        phi = np.arctan2(srs[..., 1], srs[..., 0])
        zeta = np.arcsin(np.clip(srs[..., 2], -1.0, 1.0))
        spin = axes[:, :, 2]  # (steps, 3)
        for name, azimuth, (lo_deg, hi_deg) in fovs:
            r = np.mod(phi - azimuth + math.pi, 2.0 * math.pi) - math.pi
            hit = (r[:-1] > 0) & (r[1:] <= 0) & (r[:-1] - r[1:] < math.pi)
            ti, si = np.nonzero(hit)
            w = r[ti, si] / (r[ti, si] - r[ti + 1, si])
            tt = t[ti] + w * step
            zz = np.degrees(zeta[ti, si] + w * (zeta[ti + 1, si] - zeta[ti, si]))
            ok = (zz > lo_deg) & (zz < hi_deg) & (tt >= start_jd) & (tt < end_jd)
            ti, si, w, tt, zz = ti[ok], si[ok], w[ok], tt[ok], zz[ok]
            z_spin = spin[ti] + w[:, None] * (spin[ti + 1] - spin[ti])
            psi = np.degrees(np.arctan2(np.sum(z_spin * north[si], 1), -np.sum(z_spin * east[si], 1)))
            rows.append(pd.DataFrame({"source_index": si, "tcb_jd": tt, "fov": name,
                                      "scan_angle_deg": np.mod(psi, 360.0), "ac_offset_deg": zz}))
    out = pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(
        columns=["source_index", "tcb_jd", "fov", "scan_angle_deg", "ac_offset_deg"])
    return out.sort_values(["source_index", "tcb_jd"], kind="stable").reset_index(drop=True)
