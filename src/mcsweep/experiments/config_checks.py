"""The checks every config section runs in ``__post_init__``: each failure is one line naming
the key, the value and what is accepted (:class:`mcsweep.errors.UserInputError`)."""

from __future__ import annotations

from typing import Any

from ..errors import UserInputError

__all__ = ["require", "tcb_jd_checked", "check_reference_epoch"]


def require(ok: bool, key: str, value: Any, accepted: str) -> None:
    if not ok:
        raise UserInputError(f"{key}={value!r} is not accepted; expected {accepted}")


def tcb_jd_checked(key: str, iso: str) -> float:
    """TCB Julian date of an ISO date inside the observer-ephemeris table, else a one-line error."""
    from ..scanning.ephemeris import TABLE_END_JD_TCB, TABLE_START_JD_TCB
    from ..scanning.timescale import tcb_jd

    jd = tcb_jd(str(iso), key)
    require(TABLE_START_JD_TCB <= jd <= TABLE_END_JD_TCB, key, iso, "a date within 2013-2031 (TCB)")
    return jd


def check_reference_epoch(key: str, value: str) -> None:
    """A reference-epoch setting: 'dataset_mean', 'star_mean' or an ISO date within 2013-2031 (TCB)."""
    if value in ("dataset_mean", "star_mean"):
        return
    try:
        tcb_jd_checked(key, value)
    except UserInputError:
        raise UserInputError(f"{key}={value!r} is not accepted; expected 'dataset_mean', 'star_mean' or an "
                             "ISO date within 2013-2031 (TCB) such as '2017-01-23T00:00:00'") from None
