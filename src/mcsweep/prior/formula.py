"""The all-sky parallax prior sigma_F90(l, b, G) of the paper (Sect. 3.4, Eqs. 14-17)::

    log10 sigma_F90 = s0(G) + s1(G) |sin b| + s2(G) cos b cos l  (Eq. 14)
    s0(G) = 2.187 - 0.2547 G + 0.006382 G^2                   (Eq. 15)
    s1(G) = 0.114 - 0.0579 G + 0.01369 G^2 - 0.000506 G^3     (Eq. 16)
    s2(G) = 0.031 - 0.0062 G                                  (Eq. 17)

with sigma_F90 in mas and (l, b) galactic coordinates. The proper-motion prior is
``sigma_mu = R sigma_F90`` with R = 10/yr (Eq. 18, ``mcsweep.astrometry.solve``).

Magnitude range. The coefficients were fitted to G = 6-20 (GUMS, 1 mag bins).

* G > 20: the value at G = 20 is used, as the paper prescribes (Sect. 3.4: GUMS is
  complete only to G = 20 and fainter stars have smaller parallaxes, so the G = 20
  prior is a conservative over-estimate).
* G < 6: the paper recommends Hipparcos/Tycho-2 priors instead, which are outside
  this package. Our choice, ``bright="extrapolate"`` (default), evaluates the
  polynomials below G = 6. Reason: the paper shows (Sect. 3.3) that sigma_F90 is a
  lower limit: a prior up to ~10 times larger keeps the errors at the same level with
  conservative formal uncertainties, while a smaller prior underestimates them.
  Brighter stars are nearer, so clamping at G = 6 would give a prior that is too
  tight, whereas the extrapolation keeps growing smoothly (d log10 sigma / dG < 0 at
  all latitudes for G < 6; e.g. 165 mas at G = 0, l = b = 0, comparable to the
  parallaxes of the nearest bright stars). ``bright="clamp"`` uses the G = 6 value
  instead, mirroring the faint-end rule.

The coefficient table is exposed (``PAPER_COEFFICIENTS``) and
``sigma_from_coefficients`` evaluates Eqs. 14-17 for any coefficients, so a
re-fitted prior can be evaluated with the same code (:class:`mcsweep.prior.Prior`
applies these rules for the paper's and for a run's coefficients).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np

from ..errors import UserInputError

__all__ = [
    "PAPER_COEFFICIENTS",
    "G_FIT_MIN",
    "G_FIT_MAX",
    "s_coefficients",
    "sigma_from_coefficients",
    "sigma_from_nodes",
    "BRIGHT_CHOICES",
    "check_bright",
]

#: Eqs. 15-17: coefficients of s0, s1, s2 in increasing powers of G.
PAPER_COEFFICIENTS: Mapping[str, tuple[float, ...]] = MappingProxyType({
    "s0": (2.187, -0.2547, 0.006382),
    "s1": (0.114, -0.0579, 0.01369, -0.000506),
    "s2": (0.031, -0.0062),
})

#: Magnitude range of the paper's fit (Sect. 3.4).
G_FIT_MIN = 6.0
G_FIT_MAX = 20.0

#: Treatments of stars brighter than the fit range (module notes).
BRIGHT_CHOICES = ("extrapolate", "clamp")


def check_bright(bright: str) -> str:
    """Return ``bright`` or raise UserInputError unless it is one of :data:`BRIGHT_CHOICES`."""
    if bright not in BRIGHT_CHOICES:
        raise UserInputError(f"bright={bright!r} is not accepted; expected one of {BRIGHT_CHOICES}")
    return bright


def s_coefficients(G, coefficients: Mapping[str, Sequence[float]] = PAPER_COEFFICIENTS):
    """Evaluate s0(G), s1(G), s2(G) (Eqs. 15-17) without any clamping of G.

    Parameters
    ----------
    G : array_like
        G magnitude.
    coefficients : mapping
        ``{"s0": (c0, c1, ...), "s1": (...), "s2": (...)}``, increasing powers of G.

    Returns
    -------
    s0, s1, s2 : ndarray, shape of G
    """
    g = np.asarray(G, dtype=float)
    missing = [k for k in ("s0", "s1", "s2") if k not in coefficients]
    if missing:
        raise UserInputError(f"coefficients {sorted(coefficients)} are not accepted; "
                             f"missing {missing} (expected keys s0, s1, s2)")
    out = []
    for name in ("s0", "s1", "s2"):
        c = np.asarray(coefficients[name], dtype=float)
        if c.ndim != 1 or c.size == 0 or not np.all(np.isfinite(c)):
            raise UserInputError(f"coefficients[{name!r}]={coefficients[name]!r} is not accepted; "
                                 "expected a non-empty sequence of finite numbers")
        out.append(np.polynomial.polynomial.polyval(g, c))
    return tuple(out)


def sigma_from_coefficients(l_deg, b_deg, G, coefficients: Mapping[str, Sequence[float]], *,
                            g_min=None, g_max=None) -> np.ndarray:
    """Eq. 14 with s0, s1, s2 from the given polynomial coefficients, in mas.

    Parameters
    ----------
    l_deg, b_deg : array_like
        Galactic longitude and latitude, degrees.
    G : array_like
        G magnitude. Broadcast with ``l_deg`` and ``b_deg``.
    coefficients : mapping
        As for :func:`s_coefficients`.
    g_min, g_max : float, optional, keyword-only
        Magnitudes outside ``[g_min, g_max]`` are replaced by the nearest bound before
        evaluating the polynomials (None: no bound).

    Returns
    -------
    ndarray
        sigma in mas, broadcast shape of the inputs.
    """
    l_rad = np.radians(np.asarray(l_deg, dtype=float))
    b_rad = np.radians(np.asarray(b_deg, dtype=float))
    g = np.asarray(G, dtype=float)
    if np.any(np.isnan(g)):
        raise UserInputError("G magnitude NaN is not accepted; expected finite magnitudes")
    if g_min is not None or g_max is not None:
        g = np.clip(g, g_min, g_max)
    s0, s1, s2 = s_coefficients(g, coefficients)
    return 10.0 ** (s0 + s1 * np.abs(np.sin(b_rad)) + s2 * np.cos(b_rad) * np.cos(l_rad))


def sigma_from_nodes(l_deg, b_deg, G, g_nodes, s_nodes) -> np.ndarray:
    """Eq. 14 with s0, s1, s2 interpolated linearly in G between nodes, in mas.

    The paper's first least-squares step (Sect. 3.4) gives s0, s1, s2 per G bin; Eqs. 15-17
    then smooth them with polynomials in G. ``g_nodes`` (increasing, the bins' centres) and
    ``s_nodes`` (shape (len(g_nodes), 3)) are that first step's result; between two nodes the
    terms are interpolated linearly, beyond the outer nodes they keep the outer node's value
    (the paper's rule at its faint end, Sect. 3.4).

    Parameters
    ----------
    l_deg, b_deg : array_like
        Galactic longitude and latitude, degrees.
    G : array_like
        G magnitude; broadcast with ``l_deg`` and ``b_deg``.
    g_nodes : array_like, shape (k,)
    s_nodes : array_like, shape (k, 3)

    Returns
    -------
    ndarray
        sigma in mas, broadcast shape of the inputs.
    """
    g = np.asarray(G, dtype=float)
    if np.any(np.isnan(g)):
        raise UserInputError("G magnitude NaN is not accepted; expected finite magnitudes")
    nodes = np.asarray(g_nodes, float)
    s = np.asarray(s_nodes, float)
    s0, s1, s2 = (np.interp(g, nodes, s[:, j]) for j in range(3))
    b_rad = np.radians(np.asarray(b_deg, dtype=float))
    l_rad = np.radians(np.asarray(l_deg, dtype=float))
    return 10.0 ** (s0 + s1 * np.abs(np.sin(b_rad)) + s2 * np.cos(b_rad) * np.cos(l_rad))
