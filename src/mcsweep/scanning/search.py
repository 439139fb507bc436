"""The transit search itself: intervals, candidates and refinement, for one chunk of stars.

Method (vectorised over stars in chunks, no loop over stars or transits):

1. *Nodes.* z(t) is sampled every ~0.98 day (:data:`NODE_STEP_SPIN_FRACTION` spin
   periods, less twice :data:`PREDICTION_WINDOW_DAYS`) over the searched time range;
   the span between two consecutive nodes is an *interval*.
2. *Intervals.* For a chunk of stars, ``F = U Z^T`` (float32) gives f at every node. An
   interval ``[t_k, t_k+1)`` can hold an accepted transit only if f changes sign in it or
   ``min(|f_k|, |f_k+1|) <= sin(max |zeta|) + M2 dt**2 / 8``, where M2 bounds
   ``|f''| <= |z''|`` (linear-interpolation error bound). All other intervals are dropped.
3. *Candidates.* In a kept interval, the times at which phi passes each FoV azimuth are
   predicted from phi at the two nodes: ``phi + omega_z (t - t_k)`` varies slowly
   (``d phi / dt = -omega_z`` up to terms ~ omega_precession * tan zeta) and is
   interpolated linearly, which predicts the passages to ~1 s. f there comes from the
   cubic Hermite interpolant of f and f' at the interval's nodes (error < 1e-6).
   Candidates whose predicted sin(zeta) lies outside the acceptance by more than
   :data:`PRUNE_MARGIN` are dropped.
4. *Refinement.* One Newton step on ``phi(t) = FoV azimuth`` with the full attitude
   (interpolated nu, closed-form Omega and lambda_s) at the predicted time. Since
   ``d phi / dt`` differs from the interpolated rate by < 1e-4 relative, the step leaves
   an error < 1e-4 s (5e-5 s measured over 1.8e6 transits; the tests check < 1e-3 s).
   zeta is carried to the root with the Hermite f'; the scan angle uses the spin axis
   of the evaluation (< 2 s away; error < 1e-4 deg, 5e-5 deg measured). A transit is
   kept if zeta is accepted and its time lies in the interval that proposed it, so each
   transit is found exactly once.

Segments (:mod:`mcsweep.scanning.segments`): the time range is cut at the law's segment
boundaries and each piece gets its own node grid, evaluated with its own segment's
law (the last node may lie past the piece's end: the segment's law, extrapolated).
The grids are concatenated, so one matrix product per chunk still flags the intervals of
all pieces; the interval joining two pieces is never flagged, and a transit is kept only
inside its own piece ``[lo, hi)``. A transit at a boundary therefore belongs to
exactly one segment (the one whose interval holds its time under that segment's
law), and the gaps between segments have no intervals at all.

The public entry point is :func:`mcsweep.scanning.find_transits`; this module holds the
per-chunk numerics so that :mod:`mcsweep.scanning.transits` only deals with inputs,
randomness, parallel blocks and the output table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .attitude import Attitude, SegmentedAttitude, frame_axes_from_angles, scan_frame_from_trig, spin_axis_from_trig
from .ephemeris import gaia_position_au
from .groups import assign_groups
from .law import ScanningLaw
from .timeline import keep_after_dilution

__all__ = [
    "NODE_STEP_SPIN_FRACTION",
    "PREDICTION_WINDOW_DAYS",
    "PRUNE_MARGIN",
    "Nodes",
    "ChunkBuffers",
    "build_nodes",
    "flag_intervals",
    "chunk_transits",
    "run_block",
    "spin_axis_and_rate",
]

#: Candidates predicted up to this much outside their interval are still refined [day]
#: (the prediction is good to ~1 s; this is 170 s).
PREDICTION_WINDOW_DAYS = 0.002
#: Spacing of the spin-axis nodes in spin periods (minus twice the prediction window):
#: ~0.98 day. Coarser nodes mean fewer intervals to test per star but more candidates per
#: interval; 3-8 spins are equally fast, 1 spin is ~1.8x slower.
NODE_STEP_SPIN_FRACTION = 3.95
#: Margin on sin(zeta) when pruning predicted candidates [rad]. The predicted f is good
#: to ~1e-6 (Hermite error over a ~1 day interval < 1e-6, plus the transit-time prediction
#: error ~1 s x |df/dt| < 0.15 rad/day = 2e-6).
PRUNE_MARGIN = 1e-4
# Safety factor on the numerically determined bound of |z''|.
_M2_SAFETY = 1.5
# Allowance for float32 rounding in F = U Z^T.
_FLOAT32_MARGIN = 1e-5
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, eq=False)
class Nodes:
    """Spin-axis samples on the node grids of all pieces plus what the candidate step needs.

    Interval ``c`` lies between nodes ``c`` and ``c + 1``; the intervals joining two pieces are
    not ``valid``.
    """

    interval_t0: np.ndarray   # (K+1,) start of each interval [TCB JD] (the node times)
    interval_step: np.ndarray  # (K+1,) length of each interval [day] (its piece's step)
    interval_seg: np.ndarray  # (K+1,) segment index of each interval's piece
    interval_lo: np.ndarray   # (K+1,) start of each interval's piece (transits kept in [lo, hi))
    interval_hi: np.ndarray   # (K+1,) end of each interval's piece
    valid: np.ndarray | None  # (K,) bool, False for the intervals joining two pieces; None: one piece
    max_step: float
    single: bool          # one piece: the refinement evaluates its segment directly
    z32: np.ndarray       # (K+1, 3) float32
    z: np.ndarray         # (K+1, 3)
    z_dot: np.ndarray     # (K+1, 3) [1/day]
    a: np.ndarray         # (K+1, 3) SRS x axis at Omega = 0
    b: np.ndarray         # (K+1, 3) SRS y axis at Omega = 0
    omega: np.ndarray     # (K+1,) spin phase [rad]
    threshold: float      # flag threshold on |f|

    @property
    def n_intervals(self) -> int:
        return self.z.shape[0] - 1


def spin_axis_and_rate(att: Attitude, t):
    """Spin axis z, its rate dz/dt [1/day] (ecliptic components), lambda_s, nu and Omega at ``t``."""
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


def _piece_nodes(att: Attitude, start_jd: float, end_jd: float) -> dict:
    """Node grid over one piece ``[start_jd, end_jd]`` of one segment and its flag threshold."""
    step = NODE_STEP_SPIN_FRACTION * att.law.spin_period_days - 2.0 * PREDICTION_WINDOW_DAYS
    n_intervals = max(1, math.ceil((end_jd - start_jd) / step))
    t = start_jd + step * np.arange(n_intervals + 1)
    z, z_dot, lam, nu, omega = spin_axis_and_rate(att, t)
    a, b, _ = frame_axes_from_angles(lam, nu, math.radians(att.law.solar_aspect_deg))
    # Bound on |z''| from finite differences of z' on a fine grid over the piece.
    fine_step = 0.01
    tf = np.arange(start_jd - step, end_jd + 2 * step, fine_step)
    _, zd_fine, _, _, _ = spin_axis_and_rate(att, tf)
    m2 = float(np.max(np.linalg.norm(np.diff(zd_fine, axis=0), axis=1)) / fine_step) * _M2_SAFETY
    threshold = (math.sin(math.radians(att.law.max_abs_ac_deg)) + m2 * step * step / 8.0
                 + _FLOAT32_MARGIN)
    return dict(t=t, step=step, z=z, z_dot=z_dot, a=a, b=b, omega=omega, threshold=threshold)


def build_nodes(att: SegmentedAttitude, start_jd: float, end_jd: float) -> Nodes | None:
    """Node grids over the pieces of ``[start_jd, end_jd)`` and the interval-flag threshold (steps 1-2).

    None when the time range lies entirely in a gap between segments (no transits).
    """
    pieces = att.pieces(start_jd, end_jd)
    if not pieces:
        return None
    grids = [_piece_nodes(att.parts[k], lo, hi) for k, lo, hi in pieces]
    sizes = [g["t"].size for g in grids]

    def per_node(values):
        return np.concatenate([np.full(n, v) for n, v in zip(sizes, values)])

    z = np.concatenate([g["z"] for g in grids])
    valid = None
    if len(grids) > 1:
        valid = np.ones(z.shape[0] - 1, dtype=bool)
        valid[np.cumsum(sizes)[:-1] - 1] = False  # from a piece's last node to the next piece's first
    return Nodes(interval_t0=np.concatenate([g["t"] for g in grids]),
                 interval_step=per_node([g["step"] for g in grids]),
                 interval_seg=per_node([k for k, _, _ in pieces]).astype(np.int64),
                 interval_lo=per_node([lo for _, lo, _ in pieces]), interval_hi=per_node([hi for _, _, hi in pieces]),
                 valid=valid, max_step=max(g["step"] for g in grids), single=len(grids) == 1,
                 z32=z.astype(np.float32), z=z, z_dot=np.concatenate([g["z_dot"] for g in grids]),
                 a=np.concatenate([g["a"] for g in grids]), b=np.concatenate([g["b"] for g in grids]),
                 omega=np.concatenate([g["omega"] for g in grids]),
                 # The largest piece threshold is safe for all (an interval flagged too many is only tested).
                 threshold=max(g["threshold"] for g in grids))


def _dot(u, v):
    return u[:, 0] * v[:, 0] + u[:, 1] * v[:, 1] + u[:, 2] * v[:, 2]


def _fov_specs(law: ScanningLaw):
    half = 0.5 * math.radians(law.basic_angle_deg)
    return (
        (0, half, tuple(math.radians(v) for v in law.ac_limits_p_deg)),
        (1, -half, tuple(math.radians(v) for v in law.ac_limits_f_deg)),
    )


class ChunkBuffers:
    """Work arrays of the interval-flagging step, reused across chunks (no page faults per chunk)."""

    def __init__(self, rows: int, cols: int):
        self.f32 = np.empty((rows, cols), dtype=np.float32)
        self.above = np.empty((rows, cols), dtype=bool)
        self.below = np.empty((rows, cols), dtype=bool)
        self.cls = np.empty((rows, cols), dtype=np.int8)
        self.prod = np.empty((rows, cols - 1), dtype=np.int8)


def flag_intervals(u_ecl, nodes: Nodes, buf: ChunkBuffers):
    """(star, interval) pairs whose interval may hold an accepted transit (step 2 of the module notes)."""
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
    star, interval = np.divmod(flat, nodes.n_intervals)
    if nodes.valid is not None:
        ok = nodes.valid[interval]
        star, interval = star[ok], interval[ok]
    return star, interval


def chunk_transits(u_ecl, north_ecl, east_ecl, first_index, nodes: Nodes, att: SegmentedAttitude,
                   opts: dict, buf: ChunkBuffers) -> dict:
    """All accepted transits of one chunk of stars (steps 2-4), as a dict of column arrays.

    ``opts`` holds ``dead`` (:class:`DeadTime` or None),
    ``dilution_key`` (int or None), ``dilution`` (probability) and ``compact`` (bool).
    Rows are sorted by (source, time); ``fov_code`` is 0 for P and 1 for F.
    """
    law = att.law
    omega_z = law.spin_rate_rad_day
    xi = math.radians(law.solar_aspect_deg)
    # --- 2. intervals that may hold an accepted transit
    star, interval = flag_intervals(u_ecl, nodes, buf)
    u = u_ecl[star]
    t_k = nodes.interval_t0[interval]
    step = nodes.interval_step[interval]
    f0, f1 = _dot(u, nodes.z[interval]), _dot(u, nodes.z[interval + 1])
    d0, d1 = _dot(u, nodes.z_dot[interval]) * step, _dot(u, nodes.z_dot[interval + 1]) * step
    # Azimuth phi at both nodes; its slow part phi + omega_z (t - t_k) is interpolated linearly.
    phi0 = np.arctan2(_dot(u, nodes.b[interval]), _dot(u, nodes.a[interval])) - nodes.omega[interval]
    phi1 = np.arctan2(_dot(u, nodes.b[interval + 1]), _dot(u, nodes.a[interval + 1])) - nodes.omega[interval + 1]
    slow = np.mod(phi1 - phi0 + omega_z * step + math.pi, _TWO_PI) - math.pi
    rate = omega_z - slow / step  # -d phi / dt across the interval [rad/day]
    # --- 3. candidates: predicted FoV passages and the Hermite-interpolated f there
    window = PREDICTION_WINDOW_DAYS
    n_j = math.ceil((nodes.max_step + 2.0 * window) * float(np.max(rate, initial=omega_z)) / _TWO_PI)
    cand_pair, cand_fov, cand_t, cand_df = [], [], [], []
    for fov_code, azimuth, (lo, hi) in _fov_specs(law):
        base = np.mod(phi0 - azimuth + rate * window, _TWO_PI) - rate * window
        s_lo, s_hi = math.sin(lo) - PRUNE_MARGIN, math.sin(hi) + PRUNE_MARGIN
        for j in range(n_j):
            tc = t_k + (base + _TWO_PI * j) / rate
            tau = (tc - t_k) / step
            tau2, om = tau * tau, 1.0 - tau
            fc = ((1.0 + 2.0 * tau) * om * om * f0 + tau * om * om * d0
                  + tau2 * (3.0 - 2.0 * tau) * f1 + tau2 * (tau - 1.0) * d1)
            idx = np.flatnonzero((tc < t_k + step + window) & (fc >= s_lo) & (fc <= s_hi))
            tau, tau2 = tau[idx], tau2[idx]
            # df/dt of the Hermite interpolant, to carry zeta from the evaluation to the root
            dfc = (6.0 * tau * (tau - 1.0) * (f0[idx] - f1[idx]) + (1.0 - 4.0 * tau + 3.0 * tau2) * d0[idx]
                   + (3.0 * tau2 - 2.0 * tau) * d1[idx]) / step[idx]
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
    # Each candidate in its interval's segment (near a boundary, the time alone could name the other one).
    if nodes.single:
        lam, nu, omega = att.parts[int(nodes.interval_seg[0])].lam_nu_omega(t_eval)
    else:
        lam, nu, omega = att.lam_nu_omega(t_eval, seg=nodes.interval_seg[interval[pair]])
    trig = (np.cos(lam), np.sin(lam), np.cos(nu), np.sin(nu))
    psi_w, zc = scan_frame_from_trig(u[pair], *trig, xi)
    resid = np.mod(psi_w - omega - azimuth + math.pi, _TWO_PI) - math.pi
    t = t_eval + resid / rate[pair]
    zeta = np.arcsin(np.clip(zc + f_rate * (t - t_eval), -1.0, 1.0))
    p_lo, p_hi = (math.radians(v) for v in law.ac_limits_p_deg)
    f_lo, f_hi = (math.radians(v) for v in law.ac_limits_f_deg)
    is_f = fov == 1
    tk_c = t_k[pair]
    interval_c = interval[pair]
    keep = ((zeta > np.where(is_f, f_lo, p_lo)) & (zeta < np.where(is_f, f_hi, p_hi))
            & (t >= tk_c) & (t < tk_c + step[pair]) & (t >= nodes.interval_lo[interval_c]) & (t < nodes.interval_hi[interval_c]))
    if opts["dead"] is not None:
        keep &= ~opts["dead"].is_dead(t)
    src = star[pair] + first_index
    if opts["dilution_key"] is not None:
        keep &= keep_after_dilution(opts["dilution_key"], src, is_f, t, opts["dilution"])
    idx = np.flatnonzero(keep)
    local = star[pair[idx]]
    src, t, fov, zeta = src[idx], t[idx], fov[idx], zeta[idx]
    # Scan position angle psi = atan2(d . north, d . east), d = z x u, = atan2(z . north, -z . east),
    # with the spin axis of the evaluation (< 2 s from t; it turns < 2e-6 rad/s: < 2e-4 deg).
    z_spin = spin_axis_from_trig(*(c[idx] for c in trig), xi)
    psi = np.mod(np.degrees(np.arctan2(_dot(z_spin, north_ecl[local]), -_dot(z_spin, east_ecl[local]))),
                 360.0)
    # Pairs are in (star, time) order and every kept transit lies in its pair's interval.
    order = np.argsort(pair[idx] + (t - t_k[pair[idx]]) / step[pair[idx]], kind="stable")
    src, t, fov, psi, zeta = src[order], t[order], fov[order], psi[order], zeta[order]
    if opts["compact"]:
        int_t, grp_t, flt_t = np.int32, np.int16, np.float32
    else:
        int_t, grp_t, flt_t = np.int64, np.int64, np.float64
    cols = {
        "source_index": src.astype(int_t),
        "tcb_jd": t,
        "fov_code": fov,
        "scan_angle_deg": psi.astype(flt_t),
        "ac_offset_deg": np.degrees(zeta).astype(flt_t),
        "group": assign_groups(src, t, psi).astype(grp_t),
    }
    if not opts["compact"]:
        # Compact output leaves the observer out: it is a function of tcb_jd alone
        # (mcsweep.scanning.observer_position_au), a third of the memory at 1e8 transits.
        obs = gaia_position_au(t) if t.size else np.empty((0, 3))
        cols.update(obs_x_au=obs[:, 0], obs_y_au=obs[:, 1], obs_z_au=obs[:, 2])
    return cols


def run_block(u_ecl, north_ecl, east_ecl, first_index, nodes, att, opts, chunk) -> list:
    """Transits of a block of stars, processed in chunks of ``chunk`` stars: a list of column dicts."""
    buf = ChunkBuffers(min(chunk, u_ecl.shape[0]), nodes.n_intervals + 1)
    parts = []
    for lo in range(0, u_ecl.shape[0], chunk):
        hi = min(lo + chunk, u_ecl.shape[0])
        parts.append(chunk_transits(u_ecl[lo:hi], north_ecl[lo:hi], east_ecl[lo:hi], first_index + lo,
                                    nodes, att, opts, buf))
    return parts
