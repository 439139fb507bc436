"""Reference epochs a user may name: ISO dates, Julian years ('J2017.5', '2017.5'), all TCB."""

from __future__ import annotations

import re

from ..errors import UserInputError

__all__ = ["reference_epoch_jd"]

_JYEAR = re.compile(r"^\s*J?\s*(\d{3,4}(?:\.\d*)?)\s*$", re.IGNORECASE)


def reference_epoch_jd(setting) -> float:
    """TCB Julian date of ``setting``: 'J2017.5' or '2017.5' (Julian years, TCB; J2000.0 = JD
    2451545.0 and a Julian year of 365.25 days, IAU 1976) or an ISO date such as
    '2017-07-02T09:00:00' (TCB). Raises :class:`~mcsweep.errors.UserInputError` naming the value otherwise."""
    from astropy.time import Time

    text = str(setting).strip()
    m = _JYEAR.match(text)
    try:
        if m:
            return float(Time(float(m.group(1)), format="jyear", scale="tcb").jd)
        return float(Time(text, format="isot" if "T" in text else None, scale="tcb").jd)
    except (ValueError, TypeError):
        raise UserInputError(f"--reference-epoch {setting!r} is not accepted; expected 'star_mean', a Julian "
                             "year such as 'J2017.5' or '2017.5', or an ISO date (TCB) such as "
                             "'2017-07-02T09:00:00'") from None
