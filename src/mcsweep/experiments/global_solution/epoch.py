"""Reference epoch of the global experiments (paper Sect. 2.1).

Sect. 2.1 takes the reference epoch to be "the mean epoch of observation". In a pencil
beam every star shares one set of transits, so that is the mean of those transits; in a
global solution it is the mean epoch of the data set, one epoch for all stars, as in a
global AGIS solution (Lindegren et al. 2012, A&A 538, A78, Sect. 3.2).
"""

from __future__ import annotations

import numpy as np
from astropy.time import Time

from ...astrometry.design import reference_epoch
from ...errors import UserInputError

__all__ = ["resolve_reference_epoch", "describe_reference_epoch"]


def resolve_reference_epoch(setting: str, start_tcb_jd: float, end_tcb_jd: float, tcb_jd=None,
                            mask=None) -> np.ndarray:
    """Reference epoch of each star (TCB JD), shape (n,) (n = rows of ``tcb_jd``; 1 without it).

    ``setting``: ``'dataset_mean'`` (mid-point of the observation interval, one epoch for
    all stars), ``'star_mean'`` (each star's mean epoch, needs ``tcb_jd (n, k)`` and
    ``mask``) or an ISO date (TCB).
    """
    n = 1 if tcb_jd is None else np.asarray(tcb_jd).shape[0]
    if setting == "dataset_mean":
        return np.full(n, 0.5 * (start_tcb_jd + end_tcb_jd))
    if setting == "star_mean":
        if tcb_jd is None:
            raise ValueError("star_mean needs the transit epochs")
        return reference_epoch(tcb_jd, mask)
    try:
        jd = float(Time(setting, scale="tcb").jd)
    except (ValueError, TypeError):
        raise UserInputError(f"reference_epoch={setting!r} is not accepted; expected 'dataset_mean', "
                             "'star_mean' or an ISO date (TCB) such as '2015-01-01T00:00:00'") from None
    return np.full(n, jd)


def describe_reference_epoch(setting: str, start_tcb_jd: float, end_tcb_jd: float) -> dict:
    """What a setting resolves to, for provenance and the report.

    Returns ``{"setting", "tcb_jd", "iso", "text"}``; ``tcb_jd`` and ``iso`` are None for
    ``'star_mean'`` (one epoch per star). ``text`` reads e.g. "2017-01-23 (mid-point of
    the data set, TCB)".
    """
    if setting == "star_mean":
        return {"setting": setting, "tcb_jd": None, "iso": None,
                "text": "each star's own mean epoch of its retained transits (star_mean)"}
    jd = float(resolve_reference_epoch(setting, start_tcb_jd, end_tcb_jd)[0])
    iso = Time(jd, format="jd", scale="tcb").isot
    what = "mid-point of the data set" if setting == "dataset_mean" else "fixed date"
    shown = iso[:10] if setting == "dataset_mean" or iso[11:19] == "00:00:00" else iso[:19]
    return {"setting": setting, "tcb_jd": jd, "iso": iso, "text": f"{shown} ({what}, TCB)"}
