"""Reference epoch of the global experiments (paper Sect. 2.1).

Sect. 2.1 takes the reference epoch to be "the mean epoch of observation". In a pencil
beam every star shares one set of transits, so that is the mean of those transits; in a
global solution it is the mean epoch of the data set, one epoch for all stars, as in a
global AGIS solution (Lindegren et al. 2012, A&A 538, A78, Sect. 3.2).
"""

from __future__ import annotations

import numpy as np
from astropy.time import Time

from ..astrometry.design import reference_epoch
from ..errors import UserInputError

__all__ = ["resolve_reference_epoch"]


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
