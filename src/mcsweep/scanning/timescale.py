"""Epochs given by a user, as TCB Julian dates: the one conversion of the package.

Everything inside mcsweep runs on TCB (Barycentric Coordinate Time, the time scale of
Gaia's astrometric model; Lindegren et al. 2012, A&A 538, A78, Sect. 3.1). Users give
epochs as ISO strings (read as TCB), astropy Time objects (of any scale, converted by
astropy) or TCB Julian dates.
"""

from __future__ import annotations

import sys

import numpy as np

from ..errors import UserInputError

__all__ = ["tcb_jd", "iso_tcb"]


def tcb_jd(value, name: str) -> float:
    """TCB Julian date of one epoch; a UserInputError naming ``name`` if it is not one.

    Parameters
    ----------
    value : astropy.time.Time (scalar), str or float
        An astropy Time (any scale), an ISO date read as TCB (e.g.
        ``'2015-01-01T00:00:00'``) or a TCB Julian date [day].
    name : str
        The setting or argument the value came from, for the error message.
    """
    # An astropy Time exists only if astropy.time was imported; the module is imported when
    # an ISO date is read, not at import (0.2 s of every process's start).
    time_module = sys.modules.get("astropy.time")
    if time_module is not None and isinstance(value, time_module.Time):
        if value.shape != ():
            raise UserInputError(f"{name}={value!r} is not accepted; expected a scalar astropy Time")
        return float(value.tcb.jd)
    if isinstance(value, str):
        from astropy.time import Time

        try:
            return float(Time(value, scale="tcb").jd)
        except ValueError:
            raise UserInputError(f"{name}={value!r} is not accepted; expected an ISO date (TCB) such as "
                                 "'2015-01-01T00:00:00'") from None
    if isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return float(value)
    raise UserInputError(f"{name}={value!r} is not accepted; expected an astropy Time, an ISO date (TCB) "
                         "or a TCB Julian date")


def iso_tcb(jd: float) -> str:
    """ISO date (TCB, to the minute) of a TCB Julian date, for messages and reports."""
    from astropy.time import Time

    return Time(float(jd), format="jd", scale="tcb").isot[:16]
