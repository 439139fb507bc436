"""Extinction A_G along lines of sight through a smooth exponential dust disc.

The dust density is exp(-(R - R0) / h_R) exp(-|z - z_dust| / h_z), normalised to 1 in
the dust mid-plane at the solar radius, and the extinction per unit length there is
``av_per_kpc``. Defaults:

* h_R = 3.192 kpc, h_z = 103 pc and the Sun 23 pc above the dust mid-plane: Li et al.
  (2018, ApJ 858, 75), fit to the LAMOST value-added catalogue [V abstract];
* A_V / s = 0.7 mag/kpc in the mid-plane near the Sun (E(B-V) = 0.23 mag/kpc with
  R_V = 3.1, the local value of the Galaxia dust model, Sharma et al. 2011, ApJ 730, 3)
  [C]; it gives E(B-V) ~ 0.02 mag towards the Galactic poles, as in the Schlegel et al.
  (1998) maps;
* A_G / A_V = 0.789: Wang & Chen (2019, ApJ 877, 116) [C].

A smooth disc cannot reproduce local clouds (Taurus, Ophiuchus, Aquila Rift): expect
the largest count differences from GUMS (which used a 3-D map) within ~20 deg of the
plane.
"""

from __future__ import annotations

import numpy as np

from . import parameters as P

__all__ = [
    "DUST_SCALE_LENGTH_KPC",
    "DUST_SCALE_HEIGHT_PC",
    "SUN_ABOVE_DUST_PC",
    "AV_PER_KPC",
    "AG_OVER_AV",
    "DustModel",
]

DUST_SCALE_LENGTH_KPC = 3.192
DUST_SCALE_HEIGHT_PC = 103.0
SUN_ABOVE_DUST_PC = 23.0
AV_PER_KPC = 0.7
AG_OVER_AV = 0.789


class DustModel:
    """Exponential dust disc giving A_G(distance) along a line of sight.

    Parameters
    ----------
    av_per_kpc : float
        A_V per kpc in the dust mid-plane at the solar radius; 0 switches extinction off.
    scale_length_kpc, scale_height_pc : float
        Radial and vertical exponential scales of the dust.
    sun_above_dust_pc : float
        Height of the Sun above the dust mid-plane, pc.
    ag_over_av : float
        A_G / A_V.
    r0_kpc, z_sun_pc : float
        Position of the Sun (for the Galactocentric geometry).
    """

    def __init__(self, *, av_per_kpc=AV_PER_KPC, scale_length_kpc=DUST_SCALE_LENGTH_KPC,
                 scale_height_pc=DUST_SCALE_HEIGHT_PC, sun_above_dust_pc=SUN_ABOVE_DUST_PC,
                 ag_over_av=AG_OVER_AV, r0_kpc=P.R0_KPC, z_sun_pc=P.Z_SUN_PC):
        self.av_per_kpc = float(av_per_kpc)
        self.h_r = float(scale_length_kpc)
        self.h_z = float(scale_height_pc) * 1e-3
        self.z_dust = (float(z_sun_pc) - float(sun_above_dust_pc)) * 1e-3
        self.ag_over_av = float(ag_over_av)
        self.r0 = float(r0_kpc)

    def density(self, x, y, z):
        """Dust density relative to the mid-plane at the solar radius (x, y, z in kpc)."""
        R = np.sqrt(np.asarray(x) ** 2 + np.asarray(y) ** 2)
        return np.exp(-(R - self.r0) / self.h_r - np.abs(np.asarray(z) - self.z_dust) / self.h_z)

    def a_g(self, x, y, z, d_kpc):
        """Cumulative A_G along lines of sight sampled at increasing distances.

        Parameters
        ----------
        x, y, z : ndarray, shape (..., n)
            Galactocentric positions (kpc) of the sample points of each line of sight.
        d_kpc : ndarray, shape (n,)
            Heliocentric distances of the sample points, kpc, increasing, first > 0.

        Returns
        -------
        ndarray, shape (..., n)
            A_G in mag from the Sun to each sample point (trapezoid rule; the dust between
            the Sun and the first point is taken at the first point's density).
        """
        if self.av_per_kpc == 0.0:
            return np.zeros(np.shape(x))
        rho = self.density(x, y, z)
        seg = 0.5 * (rho[..., 1:] + rho[..., :-1]) * np.diff(d_kpc)
        first = rho[..., :1] * d_kpc[0]
        col = np.concatenate([first, first + np.cumsum(seg, axis=-1)], axis=-1)
        return self.ag_over_av * self.av_per_kpc * col
