"""Space velocities of model stars and their conversion to ICRS astrometry.

Velocities are drawn per component from a Gaussian velocity ellipsoid aligned with
Galactocentric cylindrical axes (sigma_U radial, sigma_V azimuthal, sigma_W vertical;
Robin et al. 2003 Table 4), around a mean rotation V_c - V_lag on a flat rotation curve.
The lag is

* thin-disc age bins: the asymmetric drift of the Jeans equation (Binney & Tremaine
  2008, Eq. 4.228, in the form of the Robin et al. 2003 erratum, A&A 416, 157),
  V_lag = -sigma_U^2 / (2 V_c) [R dln(rho)/dR + (1 - sigma_V^2/sigma_U^2)
  + (1 - sigma_W^2/sigma_U^2)], with the density gradient of the model's own density
  law at the Sun and no dispersion gradient;
* thick disc: 46 km/s (Bensby et al. 2003); halo and bulge: no net rotation.

Positions and velocities go to the ICRS through astropy's
:class:`~astropy.coordinates.Galactocentric` frame. That frame is an affine map of
Cartesian coordinates, so it is evaluated once with astropy (basis vectors through
``transform_to``) and then applied to all stars as a 3x3 matrix plus an offset; a test
compares the result with astropy star by star.
"""

from __future__ import annotations

import numpy as np
from astropy import units as u
from astropy.coordinates import (ICRS, CartesianDifferential, CartesianRepresentation,
                                 Galactic, Galactocentric)

from . import parameters as P
from .density import shape_gradient_at_sun

__all__ = ["K_KMS_PER_KPC_MASYR", "AstrometryTransform", "mean_lag_kms", "draw_velocities"]

#: 1 mas/yr at 1 kpc is 4.740470446 km/s (IAU 2012 au, Julian year).
K_KMS_PER_KPC_MASYR = 4.740470446


def mean_lag_kms(comp, *, r0_kpc=P.R0_KPC, z_sun_pc=P.Z_SUN_PC, v_circ_kms=P.V_CIRC_KMS,
                 eps_factor=1.0):
    """Mean lag behind circular rotation (km/s) of a component (see module notes)."""
    if not comp.rotates:
        return float(v_circ_kms)
    if comp.lag_kms is not None:
        return float(comp.lag_kms)
    su, sv, sw = comp.sigma_uvw
    grad = shape_gradient_at_sun(comp, r0_kpc=r0_kpc, z_sun_pc=z_sun_pc, eps_factor=eps_factor)
    bracket = grad + (1.0 - (sv / su) ** 2) + (1.0 - (sw / su) ** 2)
    return float(-su * su / (2.0 * v_circ_kms) * bracket)


def draw_velocities(x, y, lag_kms, sigma_uvw, normals, *, v_circ_kms=P.V_CIRC_KMS):
    """Galactocentric Cartesian velocities (km/s) of stars.

    Parameters
    ----------
    x, y : ndarray, shape (n,)
        Galactocentric position in the plane, kpc (Sun at x = -R0).
    lag_kms : ndarray, shape (n,)
        Mean lag of each star's component, km/s.
    sigma_uvw : ndarray, shape (n, 3)
        Velocity dispersions (radial, azimuthal, vertical), km/s.
    normals : ndarray, shape (3, n)
        Standard normal deviates.
    v_circ_kms : float
        Circular velocity, km/s.

    Returns
    -------
    ndarray, shape (3, n)
        (v_x, v_y, v_z) in the Galactocentric frame, km/s; rotation is towards +y at the
        Sun, as in astropy.
    """
    R = np.hypot(x, y)
    R = np.where(R > 0, R, 1e-9)
    cos_p, sin_p = x / R, y / R
    v_r = sigma_uvw[:, 0] * normals[0]
    v_phi = (v_circ_kms - lag_kms) + sigma_uvw[:, 1] * normals[1]
    v_z = sigma_uvw[:, 2] * normals[2]
    # e_R = (cos, sin); e_rot = (sin, -cos): +y at the Sun (x = -R0, y = 0).
    return np.stack([v_r * cos_p + v_phi * sin_p, v_r * sin_p - v_phi * cos_p, v_z])


class AstrometryTransform:
    """Galactic/Galactocentric <-> ICRS conversions through astropy's frames.

    Parameters
    ----------
    r0_kpc, z_sun_pc : float
        Galactocentric distance and height of the Sun.
    v_sun_kms : tuple of float
        Velocity of the Sun in the Galactocentric frame (U, V_c + V, W), km/s.
    """

    def __init__(self, *, r0_kpc, z_sun_pc, v_sun_kms):
        self.frame = Galactocentric(
            galcen_distance=r0_kpc * u.kpc, z_sun=z_sun_pc * u.pc,
            galcen_v_sun=CartesianDifferential(list(v_sun_kms) * u.km / u.s))
        pts = np.array([[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
        gc = ICRS(CartesianRepresentation(pts * u.kpc)).transform_to(self.frame)
        xyz = gc.cartesian.xyz.to_value(u.kpc)
        self.offset_kpc = xyz[:, 0]
        self.icrs_to_gc = xyz[:, 1:] - xyz[:, :1]
        self.v_sun_kms = np.asarray(v_sun_kms, float)
        gal = Galactic(CartesianRepresentation(np.eye(3) * u.one)).transform_to(ICRS())
        self.gal_to_icrs = gal.cartesian.xyz.value

    def icrs_unit(self, l_deg, b_deg):
        """ICRS unit vectors (3, n) of Galactic directions."""
        l, b = np.radians(l_deg), np.radians(b_deg)
        cb = np.cos(b)
        return self.gal_to_icrs @ np.stack([cb * np.cos(l), cb * np.sin(l), np.sin(b)])

    def galactocentric_position(self, l_deg, b_deg, d_kpc):
        """Galactocentric Cartesian position (3, n), kpc, as astropy computes it."""
        return self.icrs_to_gc @ (self.icrs_unit(l_deg, b_deg) * d_kpc) + self.offset_kpc[:, None]

    def astrometry(self, l_deg, b_deg, d_kpc, v_gc_kms, *, gal_unit=None):
        """ICRS position and proper motion of stars.

        Parameters
        ----------
        l_deg, b_deg : ndarray, shape (n,)
            Galactic coordinates, deg.
        gal_unit : ndarray, shape (3, n), optional
            Galactic Cartesian unit vectors of the same directions (saves recomputing them).
        d_kpc : ndarray, shape (n,)
            Distance from the Sun, kpc.
        v_gc_kms : ndarray, shape (3, n)
            Galactocentric velocity, km/s.

        Returns
        -------
        ra_deg, dec_deg, pmra_masyr, pmdec_masyr : ndarray
            ``pmra`` includes the cos(dec) factor (Gaia convention).
        """
        n = self.icrs_unit(l_deg, b_deg) if gal_unit is None else self.gal_to_icrs @ gal_unit
        ra = np.arctan2(n[1], n[0])
        dec = np.arcsin(np.clip(n[2], -1.0, 1.0))
        v = self.icrs_to_gc.T @ (v_gc_kms - self.v_sun_kms[:, None])
        sa, ca = np.sin(ra), np.cos(ra)
        sd, cd = np.sin(dec), np.cos(dec)
        scale = 1.0 / (K_KMS_PER_KPC_MASYR * d_kpc)
        pmra = (-sa * v[0] + ca * v[1]) * scale
        pmdec = (-sd * ca * v[0] - sd * sa * v[1] + cd * v[2]) * scale
        return np.degrees(ra) % 360.0, np.degrees(dec), pmra, pmdec
