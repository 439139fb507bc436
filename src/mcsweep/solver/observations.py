"""Partial derivatives of the AL (and AC) measurements w.r.t. source and attitude parameters.

Measurements are flat arrays (one entry per AL or AC measurement), not padded per
star: the global solution couples every star to the attitude through the time of
each measurement.

Source partials are Eq. 1 of the paper, from :func:`mcsweep.astrometry.design.design_matrix`
(one call with every measurement as its own "star"), at one reference epoch.

Attitude partials. A small rotation ``delta`` (ICRS axes, mas) of the instrument moves
the apparent direction ``u`` of a star in the instrument frame by ``-delta x u``. The
AL measurement is the projection on the AL direction ``a = sin psi p + cos psi q``
(``p, q`` local east and north, ``psi`` the scan angle of Table 1), so

    dAL/d delta = -(u x a) = cos psi p - sin psi q,

and with the AC direction ``c = -cos psi p + sin psi q``,

    dAC/d delta = -(u x c) = sin psi p + cos psi q

(``r x p = q``, ``r x q = -p``). A rotation ``eps`` of all star positions,
``(dalpha*, ddelta) = (eps . q, -eps . p)``, changes AL by ``eps . (sin psi q - cos psi p)``,
exactly cancelled by ``delta = eps``: the orientation degeneracy of Sect. 6.1 of
Lindegren et al. (2012) holds exactly.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..renamed_names import old_names
from ..astrometry.design import design_matrix, tangent_triad
from .attitude_spline import AttitudeSpline

__all__ = ["Measurements", "attitude_partials", "build_measurements"]


@dataclasses.dataclass
class Measurements:
    """Normalised partials of all measurements (rows divided by their uncertainty).

    Attributes
    ----------
    star : ndarray (m,) int64
        Star of each measurement (index into the solution's stars).
    tcb_jd : ndarray (m,)
        Epoch of the measurement (TCB JD).
    t_yr : ndarray (m,)
        Epoch minus the reference epoch [Julian years], as used in ``src``.
    src : ndarray (m, 5)
        d(measurement)/d(dalpha*, ddelta, plx, pmra, pmdec) / sigma.
    att : ndarray (m, 3)
        d(measurement)/d(delta_x, delta_y, delta_z) / sigma (ICRS axes).
    j0 : ndarray (m,) int64
        First of the 4 spline coefficients touching the epoch.
    bval : ndarray (m, 4)
        Their basis values.
    is_ac : ndarray (m,) bool
        AC measurement (False: AL).
    n_stars : int
    n_coef : int
        Spline coefficients per axis.
    """

    star: np.ndarray
    tcb_jd: np.ndarray
    t_yr: np.ndarray
    src: np.ndarray
    att: np.ndarray
    j0: np.ndarray
    bval: np.ndarray
    is_ac: np.ndarray
    n_stars: int
    n_coef: int

    @property
    def size(self) -> int:
        """Number of measurements."""
        return int(self.star.size)

    def attitude_rows(self) -> np.ndarray:
        """Full attitude partials (m, 4, 3): basis value times axis partial."""
        return self.bval[:, :, None] * self.att[:, None, :]


def attitude_partials(ra_deg, dec_deg, psi_deg, *, ac: bool = False) -> np.ndarray:
    """d(AL)/d(delta) (or d(AC)/d(delta) with ``ac=True``), shape (m, 3), ICRS axes (module notes)."""
    p, q, _ = tangent_triad(ra_deg, dec_deg)
    psi = np.radians(np.asarray(psi_deg, dtype=float))[..., None]
    if ac:
        return np.sin(psi) * p + np.cos(psi) * q
    return np.cos(psi) * p - np.sin(psi) * q


def build_measurements(ra_deg, dec_deg, star, tcb_jd, psi_deg, obs_au, *, t_ref_jd: float,
                       sigma_al_mas, sigma_ac_mas=None, spline: AttitudeSpline,
                       n_stars: int | None = None) -> Measurements:
    """Partials of the AL (and AC) measurements of FoV transits.

    Parameters
    ----------
    ra_deg, dec_deg : array_like (n,)
        Reference directions of the stars (ICRS) [deg].
    star : array_like (k,) int
        Star of each FoV transit.
    tcb_jd, psi_deg : array_like (k,)
        Epoch (TCB JD) and scan angle [deg] of each transit.
    obs_au : array_like (k, 3)
        Observer's BCRS position [au].
    t_ref_jd : float, keyword-only
        The common reference epoch (paper Sect. 2.1; :mod:`mcsweep.experiments.global_solution.epoch`).
    sigma_al_mas, sigma_ac_mas : array_like (k,), keyword-only
        Measurement uncertainties; ``sigma_ac_mas=None``: AL only. Per transit, an AC
        sigma of ``inf`` drops that AC measurement.
    spline : AttitudeSpline, keyword-only
    n_stars : int, keyword-only
        Number of stars (default ``len(ra_deg)``).

    Returns
    -------
    Measurements
        AL measurements in transit order, then the AC ones.
    """
    ra = np.asarray(ra_deg, dtype=float)
    dec = np.asarray(dec_deg, dtype=float)
    star = np.asarray(star, dtype=np.int64)
    t = np.asarray(tcb_jd, dtype=float)
    psi = np.asarray(psi_deg, dtype=float)
    k = star.size
    s_al = np.broadcast_to(np.asarray(sigma_al_mas, dtype=float), (k,))
    t_yr = ((t - t_ref_jd) / 365.25)[:, None]
    ra_o, dec_o = ra[star], dec[star]
    A = design_matrix(ra_o, dec_o, t_yr, psi[:, None], np.asarray(obs_au, dtype=float)[:, None, :],
                      sigma_al_mas=s_al[:, None])
    src = [np.ascontiguousarray(A[:, 0, :])]
    att = [attitude_partials(ra_o, dec_o, psi) / s_al[:, None]]
    rows = [np.arange(k)]
    is_ac = [np.zeros(k, dtype=bool)]
    if sigma_ac_mas is not None:
        s_ac = np.broadcast_to(np.asarray(sigma_ac_mas, dtype=float), (k,))
        keep = np.isfinite(s_ac)
        if keep.any():
            sel = np.flatnonzero(keep)
            A = design_matrix(ra_o[sel], dec_o[sel], t_yr[sel], psi[sel, None],
                              np.asarray(obs_au, dtype=float)[sel, None, :],
                              sigma_al_mas=s_al[sel, None], sigma_ac_mas=s_ac[sel, None])
            src.append(np.ascontiguousarray(A[:, 1, :]))
            att.append(attitude_partials(ra_o[sel], dec_o[sel], psi[sel], ac=True) / s_ac[sel, None])
            rows.append(sel)
            is_ac.append(np.ones(sel.size, dtype=bool))
    rows = np.concatenate(rows)
    t_all = t[rows]
    j0, bval = spline.basis(t_all)
    return Measurements(star=star[rows], tcb_jd=t_all, t_yr=t_yr[rows, 0], src=np.concatenate(src),
                        att=np.concatenate(att),
                        j0=j0, bval=bval, is_ac=np.concatenate(is_ac),
                        n_stars=int(ra.size if n_stars is None else n_stars), n_coef=spline.n_coef)


#: Renamed so that "observations" is only the config group and users' tables of transits.
__getattr__ = old_names(__name__, {"Observations": "Measurements", "build_observations": "build_measurements"})
