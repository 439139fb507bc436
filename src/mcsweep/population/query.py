"""The cone-and-magnitude query shared by every population source, and its checks.

Both sources (:class:`~mcsweep.population.GalaxyModel` and
:class:`~mcsweep.population.CatalogueSource`) answer the same query and return the same
table; this module fixes the columns and turns bad query values into one-line
:class:`~mcsweep.errors.UserInputError` messages.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


from ..errors import UserInputError

__all__ = ["COLUMNS", "POPULATION_CATEGORIES", "ConeQuery"]

#: Columns of every table a source returns, in order (Gaia archive names where they exist).
COLUMNS = ("ra", "dec", "l", "b", "parallax", "pmra", "pmdec", "phot_g_mean_mag",
           "distance_pc", "population")
#: Categories of the ``population`` column of the galaxy model (catalogues may add others).
POPULATION_CATEGORIES = ("thin_disc", "thick_disc", "halo", "bulge")


def _finite(name, value):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UserInputError(f"{name}={value!r} is not accepted; expected a number") from None
    if not math.isfinite(v):
        raise UserInputError(f"{name}={value!r} is not accepted; expected a finite number")
    return v


@dataclass(frozen=True)
class ConeQuery:
    """A validated query: cone centre and radius (deg), G range (mag), optional cap.

    Use :meth:`make`, which checks the values.
    """

    l_deg: float
    b_deg: float
    radius_deg: float
    g_min: float
    g_max: float
    max_stars: int | None

    @classmethod
    def make(cls, l_deg, b_deg, radius_deg, g_min, g_max, max_stars=None):
        """Check the query values and return a :class:`ConeQuery`.

        Raises
        ------
        mcsweep.errors.UserInputError
            For non-finite values, |b| > 90 deg, a radius <= 0, g_min >= g_max, or a cap
            that is not a positive integer.
        """
        l = _finite("l_deg", l_deg) % 360.0
        b = _finite("b_deg", b_deg)
        if not -90.0 <= b <= 90.0:
            raise UserInputError(f"b_deg={b_deg!r} is not accepted; expected -90..90 deg")
        r = _finite("radius_deg", radius_deg)
        if r <= 0.0:
            raise UserInputError(f"radius_deg={radius_deg!r} is not accepted; "
                                 "expected a positive radius in deg (>= 180 for the whole sky)")
        g0, g1 = _finite("g_min", g_min), _finite("g_max", g_max)
        if not g0 < g1:
            raise UserInputError(f"g_min={g_min!r}, g_max={g_max!r} are not accepted; "
                                 "expected g_min < g_max")
        cap = None
        if max_stars is not None:
            if isinstance(max_stars, bool) or not float(max_stars).is_integer() or max_stars < 1:
                raise UserInputError(f"max_stars={max_stars!r} is not accepted; "
                                     "expected a positive integer or None")
            cap = int(max_stars)
        return cls(l, b, r, g0, g1, cap)

