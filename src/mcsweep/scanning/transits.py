"""Field-of-view transits of many directions under a scanning law.

A star at unit vector u transits a field of view when its azimuth in the scan plane,
``phi = atan2(u . y, u . x)`` in the SRS, passes the FoV azimuth (+Gamma/2 for the
preceding FoV, -Gamma/2 for the following one; phi decreases as Gaia spins) while its
across-scan offset ``zeta = asin(u . z)`` is within the FoV's acceptance. Because
|zeta| < 0.41 deg, a star is scanned only while the precessing spin axis z keeps it
within ~0.4 deg of the scan great circle, i.e. for a few hours around each zero of
``f(t) = u . z(t)`` (about 60 per star in 5 years).

Method (vectorised over stars in chunks, no loop over stars or transits):

1. *Nodes.* z(t) is sampled every ~0.98 day (:data:`NODE_STEP_SPIN_FRACTION` spin
   periods, less twice :data:`PREDICTION_WINDOW_DAYS`) over the interval.
2. *Cells.* For a chunk of stars, ``F = U Z^T`` (float32) gives f at every node. A
   cell ``[t_k, t_k+1)`` can hold an accepted transit only if f changes sign in it or
   ``min(|f_k|, |f_k+1|) <= sin(max |zeta|) + M2 dt**2 / 8``, where M2 bounds
   ``|f''| <= |z''|`` (linear-interpolation error bound). All other cells are dropped.
3. *Candidates.* In a kept cell, the times at which phi passes each FoV azimuth are
   predicted from phi at the two nodes: ``phi + omega_z (t - t_k)`` varies slowly
   (``d phi / dt = -omega_z`` up to terms ~ omega_precession * tan zeta) and is
   interpolated linearly, which predicts the passages to ~1 s. f there comes from the
   cubic Hermite interpolant of f and f' at the cell's nodes (error < 1e-6).
   Candidates whose predicted sin(zeta) lies outside the acceptance by more than
   :data:`PRUNE_MARGIN` are dropped.
4. *Refinement.* One Newton step on ``phi(t) = FoV azimuth`` with the full attitude
   (interpolated nu, closed-form Omega and lambda_s) at the predicted time. Since
   ``d phi / dt`` differs from the interpolated rate by < 1e-4 relative, the step leaves
   an error < 1e-4 s (checked in the tests). zeta is carried to the root with the
   Hermite f'; the scan angle uses the spin axis at the final time. A transit is kept
   if zeta is accepted and its time lies in the cell that proposed it, so each transit
   is found exactly once.

Transit times are TCB Julian dates at Gaia. The observer's barycentric position at
each transit comes from :func:`mcsweep.scanning.ephemeris.gaia_position_au` (one
spline evaluation per transit, no ephemeris call per star).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from astropy.time import Time

from ..errors import UserInputError
from .attitude import (Attitude, attitude_for, frame_axes_from_angles, scan_frame_components,
                       spin_axis_from_angles)
from .ephemeris import TABLE_END_JD_TCB, TABLE_START_JD_TCB, gaia_position_au
from .frames import ICRS_TO_ECLIPTIC, local_north_east, unit_vector
from .groups import assign_groups
from .law import ScanningLaw
from .timeline import draw_dead_time, dilution_key, keep_after_dilution

__all__ = [
    "find_transits",
    "TRANSIT_COLUMNS",
    "NODE_STEP_SPIN_FRACTION",
    "PRUNE_MARGIN",
    "PREDICTION_WINDOW_DAYS",
    "DEFAULT_DEAD_TIME_BLOCK_DAYS",
]

#: Output columns, in order (see docs/architecture.md, section "scanning").
TRANSIT_COLUMNS = ("source_index", "tcb_jd", "fov", "scan_angle_deg", "ac_offset_deg", "group",
                   "obs_x_au", "obs_y_au", "obs_z_au")
#: Candidates predicted up to this much outside their cell are still refined [day]
#: (the prediction is good to ~1 s; this is 170 s).
PREDICTION_WINDOW_DAYS = 0.002
#: Spacing of the spin-axis nodes in spin periods (minus twice the prediction window):
#: ~0.98 day. Coarser nodes mean fewer cells to test per star but more candidates per
#: cell; 3-8 spins are equally fast, 1 spin is ~1.8x slower.
NODE_STEP_SPIN_FRACTION = 3.95
#: Margin on sin(zeta) when pruning predicted candidates [rad]. The predicted f is good
#: to < 1e-6 (Hermite error < 1e-8, transit-time prediction error ~1 s x |df/dt| < 0.15 rad/day).
PRUNE_MARGIN = 1e-4
#: Default length of one dead-time block [day] (about one spin; the paper gives no gap lengths).
DEFAULT_DEAD_TIME_BLOCK_DAYS = 0.25
# Safety factor on the numerically determined bound of |z''|.
_M2_SAFETY = 1.5
# Allowance for float32 rounding in F = U Z^T.
_FLOAT32_MARGIN = 1e-5
# Target number of float32 entries of F per chunk (~8 MB).
_F_ENTRIES_PER_CHUNK = 4_000_000
# Stars per joblib task when n_jobs != 1.
_STARS_PER_BLOCK = 50_000
_TWO_PI = 2.0 * math.pi


def _tcb_jd(t, name: str) -> float:
    if isinstance(t, Time):
        if t.shape != ():
            raise UserInputError(f"{name}={t!r} is not accepted; expected a scalar astropy Time")
        return float(t.tcb.jd)
    if isinstance(t, str):
        try:
            return float(Time(t, scale="tcb").jd)
        except ValueError:
            raise UserInputError(f"{name}={t!r} is not accepted; expected an ISO date (TCB) or astropy Time") from None
    if isinstance(t, (int, float, np.floating, np.integer)) and not isinstance(t, bool):
        return float(t)
    raise UserInputError(f"{name}={t!r} is not accepted; expected an astropy Time, an ISO date (TCB) "
                         "or a TCB Julian date")


@dataclass(frozen=True, eq=False)
class _Nodes:
    """Spin-axis samples on the node grid plus what the candidate step needs."""

    t0: float
    step: float
    z32: np.ndarray       # (K+1, 3) float32
    z: np.ndarray         # (K+1, 3)
    z_dot: np.ndarray     # (K+1, 3) [1/day]
    a: np.ndarray         # (K+1, 3) SRS x axis at Omega = 0
    b: np.ndarray         # (K+1, 3) SRS y axis at Omega = 0
    omega: np.ndarray     # (K+1,) spin phase [rad]
    threshold: float      # flag threshold on |f|

    @property
    def n_cells(self) -> int:
        return self.z.shape[0] - 1


def _spin_axis_and_rate(att: Attitude, t):
    lam, lam_dot, nu, nu_dot, omega, _ = att.heliotropic(t)
    xi = math.radians(att.law.solar_aspect_deg)
    sx, cx = math.sin(xi), math.cos(xi)
    cl, sl, cn, sn = np.cos(lam), np.sin(lam), np.cos(nu), np.sin(nu)
    # z' = (cx, sx cn, sx sn) in the Sun frame, rotated by lambda_s about the ecliptic pole.
    zx = cl * cx - sl * sx * cn
    zy = sl * cx + cl * sx * cn
    zz = sx * sn
    # dz/dt = lambda_s' (k x z) + R_z(lambda_s) dz'/dnu nu'
    dpy, dpz = -sx * sn * nu_dot, sx * cn * nu_dot
    dzx = -lam_dot * zy - sl * dpy
    dzy = lam_dot * zx + cl * dpy
    dzz = dpz
    return np.stack([zx, zy, zz], -1), np.stack([dzx, dzy, dzz], -1), lam, nu, omega


def _build_nodes(att: Attitude, start_jd: float, end_jd: float) -> _Nodes:
    step = NODE_STEP_SPIN_FRACTION * att.law.spin_period_days - 2.0 * PREDICTION_WINDOW_DAYS
    n_cells = max(1, math.ceil((end_jd - start_jd) / step))
    t = start_jd + step * np.arange(n_cells + 1)
    z, z_dot, lam, nu, omega = _spin_axis_and_rate(att, t)
    a, b, _ = frame_axes_from_angles(lam, nu, math.radians(att.law.solar_aspect_deg))
    # Bound on |z''| from finite differences of z' on a fine grid over the interval.
    fine_step = 0.01
    tf = np.arange(start_jd - step, end_jd + 2 * step, fine_step)
    _, zd_fine, _, _, _ = _spin_axis_and_rate(att, tf)
    m2 = float(np.max(np.linalg.norm(np.diff(zd_fine, axis=0), axis=1)) / fine_step) * _M2_SAFETY
    threshold = (math.sin(math.radians(att.law.max_abs_ac_deg)) + m2 * step * step / 8.0
                 + _FLOAT32_MARGIN)
    return _Nodes(t0=start_jd, step=step, z32=z.astype(np.float32), z=z, z_dot=z_dot, a=a, b=b,
                  omega=omega, threshold=threshold)


def _dot(u, v):
    return u[:, 0] * v[:, 0] + u[:, 1] * v[:, 1] + u[:, 2] * v[:, 2]


def _fov_specs(law: ScanningLaw):
    half = 0.5 * math.radians(law.basic_angle_deg)
    return (
        (0, half, tuple(math.radians(v) for v in law.ac_limits_p_deg)),
        (1, -half, tuple(math.radians(v) for v in law.ac_limits_f_deg)),
    )


class _Buffers:
    """Work arrays of the cell-flagging step, reused across chunks (no page faults per chunk)."""

    def __init__(self, rows: int, cols: int):
        self.f32 = np.empty((rows, cols), dtype=np.float32)
        self.above = np.empty((rows, cols), dtype=bool)
        self.below = np.empty((rows, cols), dtype=bool)
        self.cls = np.empty((rows, cols), dtype=np.int8)
        self.prod = np.empty((rows, cols - 1), dtype=np.int8)


def _flag_cells(u_ecl, nodes: _Nodes, buf: _Buffers):
    """(star, cell) pairs whose cell may hold an accepted transit (step 2 of the module notes)."""
    n = u_ecl.shape[0]
    f32, above, below = buf.f32[:n], buf.above[:n], buf.below[:n]
    cls, prod = buf.cls[:n], buf.prod[:n]
    np.matmul(u_ecl.astype(np.float32), nodes.z32.T, out=f32)
    thr = np.float32(nodes.threshold)
    np.greater(f32, thr, out=above)
    np.less(f32, -thr, out=below)
    np.subtract(above.view(np.int8), below.view(np.int8), out=cls)
    # class product <= 0: a zero class (|f| <= thr) at either end, or a sign change.
    np.multiply(cls[:, :-1], cls[:, 1:], out=prod)
    flat = np.flatnonzero(prod <= 0)
    return np.divmod(flat, nodes.n_cells)


def _chunk_transits(u_ecl, north_ecl, east_ecl, first_index, nodes: _Nodes, att: Attitude,
                    opts: dict, buf: _Buffers) -> dict:
    """All accepted transits of one chunk of stars, as a dict of column arrays."""
    law = att.law
    omega_z = law.spin_rate_rad_day
    xi = math.radians(law.solar_aspect_deg)
    start_jd, end_jd = opts["start_jd"], opts["end_jd"]
    # --- 2. cells that may hold an accepted transit
    star, cell = _flag_cells(u_ecl, nodes, buf)
    u = u_ecl[star]
    t_k = nodes.t0 + nodes.step * cell
    f0, f1 = _dot(u, nodes.z[cell]), _dot(u, nodes.z[cell + 1])
    d0, d1 = _dot(u, nodes.z_dot[cell]) * nodes.step, _dot(u, nodes.z_dot[cell + 1]) * nodes.step
    # Azimuth phi at both nodes; its slow part phi + omega_z (t - t_k) is interpolated linearly.
    phi0 = np.arctan2(_dot(u, nodes.b[cell]), _dot(u, nodes.a[cell])) - nodes.omega[cell]
    phi1 = np.arctan2(_dot(u, nodes.b[cell + 1]), _dot(u, nodes.a[cell + 1])) - nodes.omega[cell + 1]
    slow = np.mod(phi1 - phi0 + omega_z * nodes.step + math.pi, _TWO_PI) - math.pi
    rate = omega_z - slow / nodes.step  # -d phi / dt across the cell [rad/day]
    # --- 3. candidates: predicted FoV passages and the Hermite-interpolated f there
    window = PREDICTION_WINDOW_DAYS
    n_j = math.ceil((nodes.step + 2.0 * window) * float(np.max(rate, initial=omega_z)) / _TWO_PI)
    cand_pair, cand_fov, cand_t, cand_df = [], [], [], []
    for fov_code, azimuth, (lo, hi) in _fov_specs(law):
        base = np.mod(phi0 - azimuth + rate * window, _TWO_PI) - rate * window
        s_lo, s_hi = math.sin(lo) - PRUNE_MARGIN, math.sin(hi) + PRUNE_MARGIN
        for j in range(n_j):
            tc = t_k + (base + _TWO_PI * j) / rate
            tau = (tc - t_k) / nodes.step
            tau2, om = tau * tau, 1.0 - tau
            fc = ((1.0 + 2.0 * tau) * om * om * f0 + tau * om * om * d0
                  + tau2 * (3.0 - 2.0 * tau) * f1 + tau2 * (tau - 1.0) * d1)
            idx = np.flatnonzero((tc < t_k + nodes.step + window) & (fc >= s_lo) & (fc <= s_hi))
            tau, tau2 = tau[idx], tau2[idx]
            # df/dt of the Hermite interpolant, to carry zeta from the evaluation to the root
            dfc = (6.0 * tau * (tau - 1.0) * (f0[idx] - f1[idx]) + (1.0 - 4.0 * tau + 3.0 * tau2) * d0[idx]
                   + (3.0 * tau2 - 2.0 * tau) * d1[idx]) / nodes.step
            cand_pair.append(idx)
            cand_fov.append(np.full(idx.size, fov_code, dtype=np.int8))
            cand_t.append(tc[idx])
            cand_df.append(dfc)
    pair = np.concatenate(cand_pair)
    fov = np.concatenate(cand_fov)
    t_eval = np.concatenate(cand_t)
    f_rate = np.concatenate(cand_df)
    # --- 4. refinement: one Newton step on phi(t) = FoV azimuth with the full attitude
    half = 0.5 * math.radians(law.basic_angle_deg)
    azimuth = np.where(fov == 1, -half, half)
    lam, nu, omega = att.lam_nu_omega(t_eval)
    psi_w, zc = scan_frame_components(u[pair], lam, nu, xi)
    resid = np.mod(psi_w - omega - azimuth + math.pi, _TWO_PI) - math.pi
    t = t_eval + resid / rate[pair]
    zeta = np.arcsin(np.clip(zc + f_rate * (t - t_eval), -1.0, 1.0))
    p_lo, p_hi = (math.radians(v) for v in law.ac_limits_p_deg)
    f_lo, f_hi = (math.radians(v) for v in law.ac_limits_f_deg)
    is_f = fov == 1
    tk_c = t_k[pair]
    keep = ((zeta > np.where(is_f, f_lo, p_lo)) & (zeta < np.where(is_f, f_hi, p_hi))
            & (t >= tk_c) & (t < tk_c + nodes.step) & (t >= start_jd) & (t < end_jd))
    if opts["dead"] is not None:
        keep &= ~opts["dead"].is_dead(t)
    src = star[pair] + first_index
    if opts["dilution_key"] is not None:
        keep &= keep_after_dilution(opts["dilution_key"], src, is_f, t, opts["dilution"])
    idx = np.flatnonzero(keep)
    local = star[pair[idx]]
    src, t, fov, zeta = src[idx], t[idx], fov[idx], zeta[idx]
    # scan position angle psi = atan2(d . north, d . east), d = z x u, = atan2(z . north, -z . east)
    lam_t, nu_t, _ = att.lam_nu_omega(t)
    z_spin = spin_axis_from_angles(lam_t, nu_t, xi)
    psi = np.mod(np.degrees(np.arctan2(_dot(z_spin, north_ecl[local]), -_dot(z_spin, east_ecl[local]))),
                 360.0)
    # Pairs are in (star, time) order and every kept transit lies in its pair's cell.
    order = np.argsort(pair[idx] + (t - t_k[pair[idx]]) / nodes.step, kind="stable")
    src, t, fov, psi, zeta = src[order], t[order], fov[order], psi[order], zeta[order]
    int_t, grp_t, flt_t = (np.int32, np.int16, np.float32) if opts["compact"] else (np.int64, np.int64, np.float64)
    obs = gaia_position_au(t) if t.size else np.empty((0, 3))
    return {
        "source_index": src.astype(int_t),
        "tcb_jd": t,
        "fov_code": fov,
        "scan_angle_deg": psi.astype(flt_t),
        "ac_offset_deg": np.degrees(zeta).astype(flt_t),
        "group": assign_groups(src, t, fov == 1, lag_days=law.fov_lag_days).astype(grp_t),
        "obs_x_au": obs[:, 0].astype(flt_t),
        "obs_y_au": obs[:, 1].astype(flt_t),
        "obs_z_au": obs[:, 2].astype(flt_t),
    }


def _run_block(u_ecl, north_ecl, east_ecl, first_index, nodes, att, opts, chunk):
    """Transits of a block of stars, processed in chunks of ``chunk`` stars."""
    buf = _Buffers(min(chunk, u_ecl.shape[0]), nodes.n_cells + 1)
    parts = []
    for lo in range(0, u_ecl.shape[0], chunk):
        hi = min(lo + chunk, u_ecl.shape[0])
        parts.append(_chunk_transits(u_ecl[lo:hi], north_ecl[lo:hi], east_ecl[lo:hi], first_index + lo,
                                     nodes, att, opts, buf))
    return _concat(parts)


def _concat(parts: list) -> dict:
    """Concatenate column dicts, releasing every piece as soon as it is copied.

    Peak memory is then the total plus one piece, not twice the total (``np.empty``
    commits pages only when written; freed pieces are large, hence returned at once).
    """
    out = {}
    for key in list(parts[0]):
        total = sum(p[key].shape[0] for p in parts)
        col = np.empty(total, dtype=parts[0][key].dtype)
        pos = 0
        for p in parts:
            piece = p.pop(key)
            col[pos:pos + piece.shape[0]] = piece
            pos += piece.shape[0]
            del piece
        out[key] = col
    parts.clear()
    return out


def find_transits(ra_deg, dec_deg, start, end, *, law: ScanningLaw | None = None,
                  dead_time_fraction: float = 0.0, dilution: float = 0.0, rng=None,
                  dead_time_block_days: float = DEFAULT_DEAD_TIME_BLOCK_DAYS, n_jobs: int = 1,
                  compact: bool = False) -> pd.DataFrame:
    """All field-of-view transits of the given directions between ``start`` and ``end``.

    Parameters
    ----------
    ra_deg, dec_deg : array_like, shape (n,)
        ICRS right ascension and declination of the directions [deg].
    start, end : astropy.time.Time, str or float
        Interval ``[start, end)``; a string is an ISO date in TCB, a float a TCB Julian
        date. Must lie within 2013-2031 (the observer-ephemeris table).
    law : ScanningLaw, keyword-only
        Scanning law; default the flown law (``ScanningLaw()``).
    dead_time_fraction : float, keyword-only
        Fraction of the time line lost, in [0, 1) (the paper's 20 % is 0.2); drawn as
        blocks of ``dead_time_block_days`` (see :mod:`mcsweep.scanning.timeline`).
    dilution : float, keyword-only
        Probability in [0, 1] that each FoV transit is removed (the paper's 95 % is 0.95).
    rng : numpy.random.Generator, int or None, keyword-only
        Randomness for dead time and dilution (normalised with ``np.random.default_rng``);
        unused when both are 0.
    dead_time_block_days : float, keyword-only
        Length of one dead-time block [day].
    n_jobs : int, keyword-only
        Processes for joblib (1 = in process; -1 = all cores). Results do not depend on it.
    compact : bool, keyword-only
        Store ``source_index`` as int32, ``group`` as int16 and the angles and observer
        coordinates as float32 (precision 1e-5 deg and 1e-7 au), 35 instead of 65 bytes
        per transit, to hold ~10^8 transits in memory; ``tcb_jd`` stays float64.

    Returns
    -------
    pandas.DataFrame
        One row per FoV transit, sorted by (``source_index``, ``tcb_jd``), with columns
        ``source_index`` (index into the inputs), ``tcb_jd`` (transit time at Gaia, TCB
        Julian date), ``fov`` ('P' or 'F', categorical), ``scan_angle_deg`` (position
        angle psi of the scan direction, 0 = local north, 90 = local east, in [0, 360)),
        ``ac_offset_deg`` (zeta), ``group`` (0-based distinct-transit number per source,
        Table 1's "#" minus one; see :mod:`mcsweep.scanning.groups`) and
        ``obs_x_au, obs_y_au, obs_z_au`` (Gaia's BCRS position, ICRS axes).
        ``df.attrs`` holds the law, the interval and the options.

    Raises
    ------
    mcsweep.errors.UserInputError
        On malformed directions, an empty or out-of-range interval, or fractions
        outside their range.
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
    start_jd, end_jd = _tcb_jd(start, "start"), _tcb_jd(end, "end")
    if not end_jd > start_jd:
        raise UserInputError(f"interval {start}..{end} is not accepted; expected end after start")
    if start_jd < TABLE_START_JD_TCB + 1.0 or end_jd > TABLE_END_JD_TCB - 1.0:
        raise UserInputError(f"interval JD(TCB) {start_jd:.1f}..{end_jd:.1f} is not accepted; "
                             f"expected within {TABLE_START_JD_TCB + 1}..{TABLE_END_JD_TCB - 1} (2013-2031)")
    if not 0.0 <= dead_time_fraction < 1.0:
        raise UserInputError(f"dead_time_fraction={dead_time_fraction!r} is not accepted; expected [0, 1)")
    if not 0.0 <= dilution <= 1.0:
        raise UserInputError(f"dilution={dilution!r} is not accepted; expected a probability in [0, 1]")
    if not dead_time_block_days > 0.0:
        raise UserInputError(f"dead_time_block_days={dead_time_block_days!r} is not accepted; expected > 0")

    rng = np.random.default_rng(rng)
    dead = None
    if dead_time_fraction > 0.0:
        dead = draw_dead_time(start_jd, end_jd, dead_time_fraction, block_days=dead_time_block_days, rng=rng)
    dil_key = dilution_key(rng) if dilution > 0.0 else None

    att = attitude_for(law)
    nodes = _build_nodes(att, start_jd, end_jd)
    u_ecl = unit_vector(ra, dec) @ ICRS_TO_ECLIPTIC.T
    north, east = local_north_east(ra, dec)
    north_ecl, east_ecl = north @ ICRS_TO_ECLIPTIC.T, east @ ICRS_TO_ECLIPTIC.T
    opts = {"start_jd": start_jd, "end_jd": end_jd, "dead": dead, "dilution_key": dil_key,
            "dilution": dilution, "compact": compact}
    chunk = max(64, _F_ENTRIES_PER_CHUNK // (nodes.n_cells + 1))
    n = ra.size
    if n_jobs == 1 or n <= chunk:
        cols = _run_block(u_ecl, north_ecl, east_ecl, 0, nodes, att, opts, chunk)
    else:
        from joblib import Parallel, delayed

        n_blocks = max(2, math.ceil(n / _STARS_PER_BLOCK))
        edges = np.linspace(0, n, n_blocks + 1).astype(np.int64)
        blocks = Parallel(n_jobs=n_jobs)(
            delayed(_run_block)(u_ecl[a:b], north_ecl[a:b], east_ecl[a:b], int(a), nodes, att, opts, chunk)
            for a, b in zip(edges[:-1], edges[1:]) if b > a
        )
        cols = _concat(blocks)
    return _to_frame(cols, law, start_jd, end_jd,
                     attrs={"dead_time_fraction": dead_time_fraction, "dilution": dilution,
                            "dead_time_block_days": dead_time_block_days})


def _to_frame(cols: dict, law: ScanningLaw, start_jd: float, end_jd: float, attrs: dict) -> pd.DataFrame:
    data = {}
    for key in TRANSIT_COLUMNS:
        if key == "fov":
            data[key] = pd.Categorical.from_codes(cols.pop("fov_code"), categories=["P", "F"])
        else:
            data[key] = cols.pop(key)
    df = pd.DataFrame(data, copy=False)
    df.attrs.update({"scanning_law": law.name, "start_tcb_jd": start_jd, "end_tcb_jd": end_jd, **attrs})
    return df
