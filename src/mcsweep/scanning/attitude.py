"""Attitude of the scanning law: heliotropic angles integrated once per segment, then interpolated.

Heliotropic angles (ecliptic J2000 frame): nominal Sun longitude lambda_s(t), solar
aspect angle xi, precession phase nu(t), spin phase Omega(t). The attitude matrix,
taking scanning-reference-system (SRS) components to ecliptic components, is

    A = R_z(lambda_s) R_x(nu - 90 deg) R_y(90 deg - xi) R_z(Omega)

(active right-handed rotations), so the spin axis (SRS z) in the Sun-centred frame is
``(cos xi, sin xi cos nu, sin xi sin nu)``.

The Nominal Scanning Law (de Bruijne et al. 2010; Lindegren's technical notes on the
NSL) fixes nu and Omega through

    dnu/dt    = lambda_s' (sqrt(S**2 - cos**2 nu) + cos xi sin nu) / sin xi
    dOmega/dt = omega_z - cos xi dnu/dt - sin xi sin nu lambda_s'.

The law is a sequence of segments (:mod:`mcsweep.scanning.segments`): the NSL above,
the NSL with the negative root (reversed precession, dnu/dt < 0) or the EPSL (nu held
fixed, dnu/dt = 0); dOmega/dt has the same form in all. For each segment we integrate
``nu`` and ``I(t) = int sin(nu) lambda_s' dt`` once with scipy (DOP853, rtol = atol =
1e-12), in both directions from the segment's reference epoch, over the segment plus
:data:`SEGMENT_MARGIN_DAYS` (the first segment back to, the last one on to the ends
of the observer-ephemeris table: extrapolation), and tabulate both with their exact
derivatives on a regular grid. Cubic Hermite interpolation on that grid is accurate
to ~1e-11 rad. The spin phase then follows in closed form,

    Omega(t) = Omega_ref + omega_z (t - t_ref) - cos xi (nu - nu_ref) - sin xi I(t),

so the fast ``omega_z t`` term is never interpolated. :class:`Attitude` is one
segment's table; :class:`SegmentedAttitude` (what :func:`attitude_for` returns)
evaluates each epoch in its segment and gives NaN in the gaps between segments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .ephemeris import TABLE_END_JD_TCB, TABLE_START_JD_TCB
from .law import ScanningLaw
from .segments import Segment
from .sun import nominal_sun_longitude

__all__ = ["Attitude", "SegmentedAttitude", "attitude_for", "SEGMENT_MARGIN_DAYS", "scan_frame_components", "scan_frame_from_trig",
           "spin_axis_from_angles", "spin_axis_from_trig", "frame_axes_from_angles",
           "TABLE_STEP_DAYS", "ODE_RTOL"]

#: Step of the tabulated nu(t), I(t) [day]. Hermite error ~ h**4/384 |nu''''| < 1e-11 rad.
TABLE_STEP_DAYS = 1.0 / 16.0
#: Relative (and absolute, in rad) tolerance of the NSL integration.
ODE_RTOL = 1e-12
#: A segment's table reaches this far beyond its ends [day]: the transit search's last
#: node lies up to one node step (~1 day) past the end and its |z''| bound 2 steps.
SEGMENT_MARGIN_DAYS = 4.0


def _hermite(table_t0, h, y, dy, t):
    """Cubic Hermite interpolation on a regular grid; returns value and derivative."""
    s = (t - table_t0) / h
    i = np.clip(np.floor(s).astype(np.int64), 0, y.shape[0] - 2)
    tau = s - i
    tau2 = tau * tau
    one_m = 1.0 - tau
    y0, y1 = y[i], y[i + 1]
    d0, d1 = dy[i] * h, dy[i + 1] * h
    value = (1.0 + 2.0 * tau) * one_m * one_m * y0 + tau * one_m * one_m * d0 \
        + tau2 * (3.0 - 2.0 * tau) * y1 + tau2 * (tau - 1.0) * d1
    # derivative w.r.t. t
    dvalue = (6.0 * tau * (tau - 1.0) * (y0 - y1) + (1.0 - 4.0 * tau + 3.0 * tau2) * d0
              + (3.0 * tau2 - 2.0 * tau) * d1) / h
    return value, dvalue


@dataclass(frozen=True, eq=False)
class Attitude:
    """Tabulated attitude of one segment of a :class:`ScanningLaw`.

    Built by :func:`attitude_for` (cached per law), one per segment. Times are Julian
    dates in TCB [day]; angles in rad; rates in rad/day. All methods accept arrays of any
    shape and evaluate this segment's law (also outside its bounds: extrapolated).
    """

    law: ScanningLaw
    segment: Segment
    t0_jd: float
    step_days: float
    nu: np.ndarray
    nu_dot: np.ndarray
    integral: np.ndarray
    integral_dot: np.ndarray

    # -------------------------------------------------------------------- angles
    def heliotropic(self, tcb_jd):
        """Heliotropic angles and rates at ``tcb_jd``.

        Returns
        -------
        lam, lam_dot, nu, nu_dot, omega, omega_dot : ndarray
            lambda_s, nu, Omega (not wrapped) [rad] and their rates [rad/day].
        """
        t = np.asarray(tcb_jd, dtype=float)
        law = self.law
        xi = math.radians(law.solar_aspect_deg)
        lam, lam_dot = nominal_sun_longitude(t)
        nu, nu_dot = _hermite(self.t0_jd, self.step_days, self.nu, self.nu_dot, t)
        integ, integ_dot = _hermite(self.t0_jd, self.step_days, self.integral, self.integral_dot, t)
        seg = self.segment
        omega = (math.radians(seg.omega_ref_deg) + law.spin_rate_rad_day * (t - seg.ref_epoch_jd)
                 - math.cos(xi) * (nu - math.radians(seg.nu_ref_deg)) - math.sin(xi) * integ)
        omega_dot = law.spin_rate_rad_day - math.cos(xi) * nu_dot - math.sin(xi) * integ_dot
        return lam, lam_dot, nu, nu_dot, omega, omega_dot

    def matrix(self, tcb_jd) -> np.ndarray:
        """Attitude matrix A (SRS -> ecliptic J2000 components), shape ``t.shape + (3, 3)``.

        Column j of ``A`` is the SRS axis j in ecliptic components.
        """
        lam, _, nu, _, omega, _ = self.heliotropic(tcb_jd)
        xi = math.radians(self.law.solar_aspect_deg)
        return _rz(lam) @ _rx(nu - 0.5 * math.pi) @ _ry(np.full_like(lam, 0.5 * math.pi - xi)) @ _rz(omega)

    def spin_axis(self, tcb_jd) -> np.ndarray:
        """Spin axis z (ecliptic J2000 unit vector), shape ``t.shape + (3,)``."""
        lam, nu, _ = self.lam_nu_omega(tcb_jd)
        return spin_axis_from_angles(lam, nu, math.radians(self.law.solar_aspect_deg))

    def frame_axes(self, tcb_jd):
        """Axes of the non-spinning frame ``R_z(lambda_s) R_x(nu - 90) R_y(90 - xi)``.

        Returns
        -------
        a, b, z : ndarray, shape ``t.shape + (3,)``
            Ecliptic components of the SRS x and y axes at Omega = 0, and the spin axis.
            The SRS axes are ``x = cos Omega a + sin Omega b``, ``y = -sin Omega a + cos Omega b``.
        """
        lam, _, nu, _, _, _ = self.heliotropic(tcb_jd)
        return frame_axes_from_angles(lam, nu, math.radians(self.law.solar_aspect_deg))

    def lam_nu_omega(self, tcb_jd):
        """lambda_s, nu and Omega [rad] without rates (the fast path of the transit search)."""
        t = np.asarray(tcb_jd, dtype=float)
        law = self.law
        xi = math.radians(law.solar_aspect_deg)
        lam, _ = nominal_sun_longitude(t)
        h = self.step_days
        s = (t - self.t0_jd) / h
        i = np.clip(np.floor(s).astype(np.int64), 0, self.nu.shape[0] - 2)
        tau = s - i
        tau2 = tau * tau
        one_m2 = (1.0 - tau) * (1.0 - tau)
        h00, h10 = (1.0 + 2.0 * tau) * one_m2, tau * one_m2 * h
        h01, h11 = tau2 * (3.0 - 2.0 * tau), tau2 * (tau - 1.0) * h
        j = i + 1
        nu = h00 * self.nu[i] + h10 * self.nu_dot[i] + h01 * self.nu[j] + h11 * self.nu_dot[j]
        integ = (h00 * self.integral[i] + h10 * self.integral_dot[i] + h01 * self.integral[j]
                 + h11 * self.integral_dot[j])
        seg = self.segment
        omega = (math.radians(seg.omega_ref_deg) + law.spin_rate_rad_day * (t - seg.ref_epoch_jd)
                 - math.cos(xi) * (nu - math.radians(seg.nu_ref_deg)) - math.sin(xi) * integ)
        return lam, nu, omega

    def srs_components(self, u_ecl, tcb_jd):
        """Components of directions ``u_ecl (..., 3)`` in the SRS at ``tcb_jd (...)``.

        Returns
        -------
        psi_w, z, omega : ndarray
            ``psi_w = atan2(u . b, u . a)`` (azimuth at Omega = 0) [rad], ``z = u . z_spin``
            (= sin zeta) and the spin phase Omega [rad]. The azimuth in the scan plane is
            ``phi = psi_w - Omega`` (mod 2 pi).
        """
        lam, nu, omega = self.lam_nu_omega(tcb_jd)
        psi_w, z = scan_frame_components(u_ecl, lam, nu, math.radians(self.law.solar_aspect_deg))
        return psi_w, z, omega


def scan_frame_components(u_ecl, lam, nu, xi):
    """Azimuth at Omega = 0 and spin-axis component of ``u_ecl`` for given angles.

    Parameters
    ----------
    u_ecl : ndarray, shape (..., 3)
        Unit vectors, ecliptic J2000 components.
    lam, nu : ndarray
        Nominal Sun longitude and precession phase [rad] (broadcast with ``u_ecl[..., 0]``).
    xi : float
        Solar aspect angle [rad].

    Returns
    -------
    psi_w, z : ndarray
        ``atan2(u . b, u . a)`` [rad] and ``u . z_spin`` (see :meth:`Attitude.frame_axes`).
    """
    return scan_frame_from_trig(u_ecl, np.cos(lam), np.sin(lam), np.cos(nu), np.sin(nu), xi)


def scan_frame_from_trig(u_ecl, cos_lam, sin_lam, cos_nu, sin_nu, xi):
    """:func:`scan_frame_components` from the cosines and sines of lambda_s and nu."""
    ux, uy, uz = u_ecl[..., 0], u_ecl[..., 1], u_ecl[..., 2]
    # R_z(-lambda_s)
    x1 = cos_lam * ux + sin_lam * uy
    y1 = cos_lam * uy - sin_lam * ux
    # R_x(-(nu - 90 deg)): cos(nu - 90) = sin nu, sin(nu - 90) = -cos nu
    y2 = sin_nu * y1 - cos_nu * uz
    z2 = cos_nu * y1 + sin_nu * uz
    # R_y(-(90 deg - xi)): cos = sin xi, sin = cos xi
    sx, cx = math.sin(xi), math.cos(xi)
    x3 = sx * x1 - cx * z2
    z3 = cx * x1 + sx * z2
    return np.arctan2(y2, x3), z3


def spin_axis_from_angles(lam, nu, xi) -> np.ndarray:
    """Spin axis (ecliptic J2000 unit vector, shape ``(..., 3)``) for angles lam, nu, xi [rad]."""
    return spin_axis_from_trig(np.cos(lam), np.sin(lam), np.cos(nu), np.sin(nu), xi)


def spin_axis_from_trig(cos_lam, sin_lam, cos_nu, sin_nu, xi) -> np.ndarray:
    """:func:`spin_axis_from_angles` from the cosines and sines of lambda_s and nu."""
    sx, cx = math.sin(xi), math.cos(xi)
    return np.stack(np.broadcast_arrays(cos_lam * cx - sin_lam * sx * cos_nu,
                                        sin_lam * cx + cos_lam * sx * cos_nu, sx * sin_nu), axis=-1)


def frame_axes_from_angles(lam, nu, xi):
    """Axes a, b, z of the non-spinning frame for angles lam, nu, xi [rad].

    See :meth:`Attitude.frame_axes`.
    """
    cl, sl = np.cos(lam), np.sin(lam)
    cn, sn = np.cos(nu), np.sin(nu)
    sx, cx = math.sin(xi), math.cos(xi)
    # Columns of R_z(lam) R_x(nu - 90) R_y(90 - xi) in ecliptic components.
    # Sun-centred frame first: a' = (sin xi, -cos xi cos nu, -cos xi sin nu),
    # b' = (0, sin nu, -cos nu), z' = (cos xi, sin xi cos nu, sin xi sin nu).
    def rot(x, y, zc):
        return np.stack(np.broadcast_arrays(cl * x - sl * y, sl * x + cl * y, zc), axis=-1)

    a = rot(sx * np.ones_like(nu), -cx * cn, -cx * sn)
    b = rot(np.zeros_like(nu), sn, -cn)
    z = rot(cx * np.ones_like(nu), sx * cn, sx * sn)
    return a, b, z


def _rz(a):
    a = np.asarray(a, dtype=float)
    c, s, o, i = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, o], -1), np.stack([s, c, o], -1), np.stack([o, o, i], -1)], -2)


def _rx(a):
    a = np.asarray(a, dtype=float)
    c, s, o, i = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([i, o, o], -1), np.stack([o, c, -s], -1), np.stack([o, s, c], -1)], -2)


def _ry(a):
    a = np.asarray(a, dtype=float)
    c, s, o, i = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, o, s], -1), np.stack([o, i, o], -1), np.stack([-s, o, c], -1)], -2)


def _nsl_rates(law: ScanningLaw, nu, lam_dot, root_sign: float = 1.0):
    """Rates (dnu/dt, d/dt of the Omega integral) for precession phase ``nu`` [rad].

    dnu/dt = lambda_s' (+-sqrt(S^2 - cos^2 nu) + cos xi sin nu) / sin xi (``root_sign``
    +1: NSL, -1: reversed precession; 0: EPSL, dnu/dt = 0), and the integral term
    sin(nu) lambda_s' of dOmega/dt (module notes).
    """
    xi = math.radians(law.solar_aspect_deg)
    sin_nu = np.sin(nu)
    if root_sign == 0.0:
        return np.zeros_like(sin_nu * lam_dot), sin_nu * lam_dot
    root = np.sqrt(law.precession_S ** 2 - np.cos(nu) ** 2)
    if root_sign < 0.0:
        root = -root
    nu_dot = lam_dot * (root + math.cos(xi) * sin_nu) / math.sin(xi)
    return nu_dot, sin_nu * lam_dot


def _nsl_rhs(law: ScanningLaw, root_sign: float = 1.0):
    def rhs(t, y):
        _, lam_dot = nominal_sun_longitude(t)
        return np.array(_nsl_rates(law, y[0], lam_dot, root_sign))

    return rhs


def _segment_table(law: ScanningLaw, seg: Segment, lo_jd: float, hi_jd: float) -> Attitude:
    """One ODE integration of ``seg``'s law over ``[lo_jd, hi_jd]`` (and its reference epoch), tabulated."""
    rhs = _nsl_rhs(law, seg.root_sign)
    t_ref = seg.ref_epoch_jd
    h = TABLE_STEP_DAYS
    n_lo = max(0, math.ceil((t_ref - lo_jd) / h))
    n_hi = max(0, math.ceil((hi_jd - t_ref) / h))
    grid = t_ref + h * np.arange(-n_lo, n_hi + 1)
    from scipy.integrate import solve_ivp  # 0.3 s of imports, for the processes that tabulate the law

    y0 = np.array([math.radians(seg.nu_ref_deg), 0.0])
    values = np.empty((grid.size, 2))
    values[n_lo] = y0
    for sl, t_end in ((slice(n_lo, None), grid[-1]), (slice(n_lo, None, -1), grid[0])):
        ts = grid[sl]
        if ts.size < 2:
            continue
        sol = solve_ivp(rhs, (t_ref, t_end), y0, method="DOP853", t_eval=ts,
                        rtol=ODE_RTOL, atol=ODE_RTOL)
        if not sol.success:  # pragma: no cover - a smooth ODE with S > 1
            raise RuntimeError(f"scanning-law integration failed ({seg.label()}): {sol.message}")
        values[sl] = sol.y.T
    nu, integral = values[:, 0], values[:, 1]
    _, lam_dot = nominal_sun_longitude(grid)
    nu_dot, integral_dot = _nsl_rates(law, nu, lam_dot, seg.root_sign)
    for arr in (grid, nu, nu_dot, integral, integral_dot):
        arr.setflags(write=False)
    return Attitude(law=law, segment=seg, t0_jd=float(grid[0]), step_days=h, nu=nu, nu_dot=nu_dot,
                    integral=integral, integral_dot=integral_dot)


@dataclass(frozen=True, eq=False)
class SegmentedAttitude:
    """The attitude of a whole :class:`ScanningLaw`: one :class:`Attitude` per segment.

    An epoch is evaluated in the segment ``[start, end)`` that holds it; before the first
    segment the first one is extrapolated, after the last one the last one; in a gap
    between two segments the angles are NaN (no attitude, no transits). Methods take
    ``seg=`` (segment index per epoch) to evaluate a segment's law just outside its
    bounds (the transit search's cells at a segment's end).
    """

    law: ScanningLaw
    parts: tuple
    #: Segment starts and ends (TCB JD), the first start -inf and the last end +inf.
    starts: np.ndarray
    ends: np.ndarray

    def segment_index(self, tcb_jd) -> np.ndarray:
        """Index of the segment holding each epoch; -1 in a gap between segments."""
        t = np.asarray(tcb_jd, dtype=float)
        k = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.parts) - 1)
        return np.where(t < self.ends[k], k, -1)

    def pieces(self, start_jd: float, end_jd: float) -> list:
        """``(segment index, lo, hi)`` of every segment overlapping ``[start_jd, end_jd)``, in time order."""
        out = []
        for k in range(len(self.parts)):
            lo, hi = max(start_jd, self.starts[k]), min(end_jd, self.ends[k])
            if hi > lo:
                out.append((k, float(lo), float(hi)))
        return out

    def _dispatch(self, name: str, tcb_jd, seg=None):
        t = np.asarray(tcb_jd, dtype=float)
        if len(self.parts) == 1:
            return getattr(self.parts[0], name)(t)
        k = self.segment_index(t) if seg is None else np.broadcast_to(np.asarray(seg), t.shape)
        tf, kf = t.reshape(-1), k.reshape(-1)
        # Epochs grouped by segment with one O(n) radix sort (small ints), so each segment's
        # table is evaluated once on a contiguous slice (the hot path of the transit search).
        order = np.argsort(kf.astype(np.int8), kind="stable")
        counts = np.bincount(kf + 1, minlength=len(self.parts) + 1)  # gap (-1) first
        ts = tf[order]
        out, single = None, False
        pos = int(counts[0])
        for i, part in enumerate(self.parts):
            c = int(counts[i + 1])
            if c == 0:
                continue
            res = getattr(part, name)(ts[pos:pos + c])
            single = not isinstance(res, tuple)
            res = (res,) if single else res
            if out is None:
                out = [np.full(tf.shape + r.shape[1:], np.nan) for r in res]
            idx = order[pos:pos + c]
            for o, r in zip(out, res):
                o[idx] = r
            pos += c
        if out is None:  # every epoch in a gap: NaN of the right shapes
            probe = getattr(self.parts[0], name)(np.array([self.parts[0].t0_jd]))
            single = not isinstance(probe, tuple)
            out = [np.full(tf.shape + p.shape[1:], np.nan) for p in ((probe,) if single else probe)]
        out = [o.reshape(t.shape + o.shape[1:]) for o in out]
        return out[0] if single else tuple(out)

    def heliotropic(self, tcb_jd, seg=None):
        """:meth:`Attitude.heliotropic` in each epoch's segment."""
        return self._dispatch("heliotropic", tcb_jd, seg)

    def lam_nu_omega(self, tcb_jd, seg=None):
        """:meth:`Attitude.lam_nu_omega` in each epoch's segment."""
        return self._dispatch("lam_nu_omega", tcb_jd, seg)

    def matrix(self, tcb_jd, seg=None) -> np.ndarray:
        """:meth:`Attitude.matrix` in each epoch's segment."""
        return self._dispatch("matrix", tcb_jd, seg)

    def spin_axis(self, tcb_jd, seg=None) -> np.ndarray:
        """:meth:`Attitude.spin_axis` in each epoch's segment."""
        return self._dispatch("spin_axis", tcb_jd, seg)

    def frame_axes(self, tcb_jd, seg=None):
        """:meth:`Attitude.frame_axes` in each epoch's segment."""
        return self._dispatch("frame_axes", tcb_jd, seg)

    def srs_components(self, u_ecl, tcb_jd, seg=None):
        """:meth:`Attitude.srs_components` in each epoch's segment (``u_ecl`` broadcast with ``tcb_jd``)."""
        lam, nu, omega = self.lam_nu_omega(tcb_jd, seg)
        psi_w, z = scan_frame_components(u_ecl, lam, nu, math.radians(self.law.solar_aspect_deg))
        return psi_w, z, omega


@lru_cache(maxsize=4)
def attitude_for(law: ScanningLaw) -> SegmentedAttitude:
    """Integrate each segment of ``law`` once and tabulate it (cached per law).

    Together the tables span the observer-ephemeris table (2013-2031, see
    :mod:`mcsweep.scanning.ephemeris`), so any epoch accepted there is accepted here.
    """
    segs = law.segment_list
    parts = []
    for k, seg in enumerate(segs):
        lo = TABLE_START_JD_TCB if k == 0 else max(TABLE_START_JD_TCB, seg.start_jd - SEGMENT_MARGIN_DAYS)
        hi = TABLE_END_JD_TCB if k == len(segs) - 1 else min(TABLE_END_JD_TCB, seg.end_jd + SEGMENT_MARGIN_DAYS)
        parts.append(_segment_table(law, seg, lo, hi))
    starts = np.array([-math.inf] + [s.start_jd for s in segs[1:]])
    ends = np.array([s.end_jd for s in segs[:-1]] + [math.inf])
    for arr in (starts, ends):
        arr.setflags(write=False)
    return SegmentedAttitude(law=law, parts=tuple(parts), starts=starts, ends=ends)
