"""Density laws of the stellar components (Robin et al. 2003, Table 3).

Each law is returned as a *shape*: the density relative to its value at the component's
reference point (the Sun for the discs and the halo, the Galactic centre for the bulge).
The absolute normalisation, in stars per pc^3 per magnitude, comes from the luminosity
function (:mod:`.luminosity`).

Coordinates are Galactocentric Cartesian in kpc with the Sun at ``(-r0, 0, z_sun)``
(astropy's Galactocentric convention; the tiny tilt astropy applies for ``z_sun`` is
ignored here, it moves points by < 0.1 %).

Simplifications (stated once here): no warp and no flare of the discs (they change the
outer disc at |b| < 10 deg), no spiral arms, bulge tilt and roll angles neglected.
"""

from __future__ import annotations

import numpy as np

from . import parameters as P

__all__ = [
    "heliocentric_to_galactocentric",
    "component_shape",
    "shape_gradient_at_sun",
]


def heliocentric_to_galactocentric(l_deg, b_deg, d_kpc, *, r0_kpc=P.R0_KPC,
                                   z_sun_pc=P.Z_SUN_PC):
    """Galactocentric Cartesian position of points given in Galactic coordinates.

    Parameters
    ----------
    l_deg, b_deg : array_like
        Galactic longitude and latitude, deg.
    d_kpc : array_like
        Heliocentric distance, kpc (broadcast against the angles).
    r0_kpc : float
        Galactocentric distance of the Sun, kpc.
    z_sun_pc : float
        Height of the Sun above the plane, pc.

    Returns
    -------
    x, y, z : ndarray
        Position in kpc; the Sun is at (-r0, 0, z_sun), y points to l = 90 deg.
    """
    l = np.radians(l_deg)
    b = np.radians(b_deg)
    cb = np.cos(b)
    x = np.asarray(d_kpc) * cb * np.cos(l) - r0_kpc
    y = np.asarray(d_kpc) * cb * np.sin(l)
    z = np.asarray(d_kpc) * np.sin(b) + z_sun_pc * 1e-3
    return x, y, z


def _einasto(R, z, eps, h_plus, h_minus, young):
    a2 = R * R + (z / eps) ** 2
    if young:
        return np.exp(-a2 / h_plus ** 2) - np.exp(-a2 / h_minus ** 2)
    return (np.exp(-np.sqrt(0.25 + a2 / h_plus ** 2))
            - np.exp(-np.sqrt(0.25 + a2 / h_minus ** 2)))


def _thick(R, z, r0):
    hz, xl = P.THICK_DISC_HZ_KPC, P.THICK_DISC_XL_KPC
    az = np.abs(z)
    inner = 1.0 - z * z / (xl * (2.0 * hz + xl))
    outer = np.exp(xl / hz) / (1.0 + xl / (2.0 * hz)) * np.exp(-az / hz)
    return np.exp(-(R - r0) / P.THICK_DISC_HR_KPC) * np.where(az <= xl, inner, outer)


def _halo(R, z, eps):
    a = np.sqrt(R * R + (z / eps) ** 2)
    return np.maximum(a, P.HALO_CORE_KPC) ** (-P.HALO_POWER)


def _bulge(x, y, z):
    ang = np.radians(P.BULGE_ANGLE_DEG)
    # Bar frame: major axis xb at BULGE_ANGLE_DEG from the Sun-centre line (+x, the Sun
    # is at negative x), near end at positive longitude, i.e. at x < 0, y > 0.
    xb = x * np.cos(ang) - y * np.sin(ang)
    yb = x * np.sin(ang) + y * np.cos(ang)
    rs2 = np.sqrt(((xb / P.BULGE_X0_KPC) ** 2 + (yb / P.BULGE_Y0_KPC) ** 2) ** 2
                  + (z / P.BULGE_Z0_KPC) ** 4)
    rho = np.exp(-0.5 * rs2)
    rcyl = np.sqrt(x * x + y * y)
    taper = np.exp(-0.5 * ((rcyl - P.BULGE_RC_KPC) / P.BULGE_TAPER_KPC) ** 2)
    return np.where(rcyl > P.BULGE_RC_KPC, rho * taper, rho)


def _raw(comp, x, y, z, *, r0_kpc, eps_factor):
    R = np.sqrt(x * x + y * y)
    if comp.law in ("einasto", "einasto_young"):
        young = comp.law == "einasto_young"
        h = P.EINASTO_YOUNG_H_KPC if young else P.EINASTO_OLD_H_KPC
        rho = _einasto(R, z, comp.eps * eps_factor, h[0], h[1], young)
        return np.where(R <= P.DISC_CUTOFF_KPC, rho, 0.0)
    if comp.law == "thick":
        return np.where(R <= P.DISC_CUTOFF_KPC, _thick(R, z, r0_kpc), 0.0)
    if comp.law == "halo":
        return _halo(R, z, comp.eps)
    if comp.law == "bulge":
        return _bulge(x, y, z)
    raise ValueError(f"unknown density law {comp.law!r}")


def component_shape(comp, x, y, z, *, r0_kpc=P.R0_KPC, z_sun_pc=P.Z_SUN_PC,
                    eps_factor=1.0):
    """Density of a component relative to its reference point.

    Parameters
    ----------
    comp : parameters.Component
        The component.
    x, y, z : array_like
        Galactocentric position, kpc.
    r0_kpc, z_sun_pc : float
        Position of the Sun (kpc, pc): the reference point of discs and halo.
    eps_factor : float
        Multiplies the thin-disc Einasto axis ratios (scales the thin-disc thickness).

    Returns
    -------
    ndarray
        rho(x, y, z) / rho(reference point), dimensionless.
    """
    if comp.law == "bulge":
        ref = 1.0
    else:
        ref = float(_raw(comp, np.array(-r0_kpc), np.array(0.0), np.array(z_sun_pc * 1e-3),
                         r0_kpc=r0_kpc, eps_factor=eps_factor))
    return _raw(comp, x, y, z, r0_kpc=r0_kpc, eps_factor=eps_factor) / ref


def shape_gradient_at_sun(comp, *, r0_kpc=P.R0_KPC, z_sun_pc=P.Z_SUN_PC, eps_factor=1.0,
                          step_kpc=0.01):
    """Logarithmic radial gradient R dln(rho)/dR at the Sun (dimensionless).

    Used by the Jeans-equation asymmetric drift (:mod:`.kinematics`).
    """
    z = z_sun_pc * 1e-3
    lo = component_shape(comp, -(r0_kpc - step_kpc), 0.0, z, r0_kpc=r0_kpc,
                         z_sun_pc=z_sun_pc, eps_factor=eps_factor)
    hi = component_shape(comp, -(r0_kpc + step_kpc), 0.0, z, r0_kpc=r0_kpc,
                         z_sun_pc=z_sun_pc, eps_factor=eps_factor)
    return float(r0_kpc * (np.log(hi) - np.log(lo)) / (2.0 * step_kpc))
