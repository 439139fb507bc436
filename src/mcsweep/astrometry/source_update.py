"""AGIS's source update on Gaia epoch astrometry: per-CCD AL design equations and the
weighted normal equations of each source, vectorised over sources.

Each kept AL CCD observation (:mod:`.epoch_astrometry`) gives one design equation in the
local plane of the source's reference position (Lindegren et al. 2012, A&A 538, A78,
Sect. 5.2, with the DR4 files' own parallax factor):

    w = sin(theta) da* + cos(theta) dd + P_AL plx + t sin(theta) pmra* + t cos(theta) pmdec [+ c nu]

with theta the scan position angle, P_AL the file's parallax factor (exact: it holds
Gaia's real orbit), t the barycentric time ``obs_time_tcb + obs_time_bary_corr`` in Julian
years from the reference epoch (J2017.5 TCB for DR4), and, in the six-parameter model, c
the AL colour factor and nu the pseudo-colour offset. Each equation has the weight
1 / (sigma^2 + epsilon^2), sigma the centroid's standard error and epsilon the source's
AGIS excess noise, added per CCD independently (Lindegren et al. 2012, Eqs. 62-66, with
AGIS's own epsilon fixed: no downweighting, as gaiasupdate's DR4-like update).

Six-parameter model (DR4's ``6p_constrained_colour``): the colour factor times -1e3 (the
file's per-um factor to per-nm, with AGIS's sign) and a Gaussian prior of standard
deviation 0.085e-3 nm^-1 on nu, centred on zero (both as ESA's gaiasupdate 0.1.2,
``compute_source_parameters``, reproduces AGIS DR4's solutions). nu is a nuisance
parameter here: it is eliminated from the normal equations exactly (Schur complement), so
the five astrometric parameters' normal equations are those of the 6x6 system
marginalised over nu, and every five-parameter solution (with a prior, position only, none)
applies to them unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserInputError
from .design import JULIAN_YEAR_DAYS
from .epoch_astrometry import CcdObservations

__all__ = ["MODELS", "DR4_REFERENCE_EPOCH_JD", "PSEUDOCOLOUR_PRIOR_PER_NM", "COLOUR_FACTOR_SCALE",
           "VISIBILITY_GAP_DAYS", "SourceNormals", "source_normals", "check_model", "visibility_periods"]

#: Models solved: five astrometric parameters, or DR4's six with the constrained pseudo-colour.
MODELS = ("5p", "6p")
#: J2017.5 as a TCB Julian date, 2451545.0 + 17.5 x 365.25: the reference epoch of Gaia DR4
#: (gaiasupdate's DR4_REFERENCE_EPOCH, Time('2017.5', format='jyear', scale='tcb')).
DR4_REFERENCE_EPOCH_JD = 2457936.875
#: Prior standard deviation of the pseudo-colour offset, nm^-1 (gaiasupdate 0.1.2,
#: compute_source_parameters: the value with which it reproduces AGIS DR4's 6p solutions).
PSEUDOCOLOUR_PRIOR_PER_NM = 0.085e-3
#: The file's AL colour factor times this is the design coefficient of nu in nm^-1 (gaiasupdate 0.1.2).
COLOUR_FACTOR_SCALE = -1e3
#: A visibility period is a group of transits separated from the next by more than 4 days
#: (the definition of gaia_source.visibility_periods_used, Lindegren et al. 2018, A&A 616, A2).
VISIBILITY_GAP_DAYS = 4.0


def check_model(model: str) -> str:
    if model not in MODELS:
        raise UserInputError(f"--model {model!r} is not accepted; expected one of {list(MODELS)}")
    return model


@dataclass(frozen=True)
class SourceNormals:
    """Per source: the five-parameter normal equations and what the observations were.

    Parameters
    ----------
    source_id : int64 (n,), increasing
        Gaia source identifiers.
    N : (n, 5, 5)
        Normal matrix in (mas, mas, mas, mas/yr, mas/yr); for the six-parameter model,
        with nu eliminated (module notes).
    b : (n, 5)
        Right-hand side, same units.
    reference_epoch_jd : (n,)
        TCB Julian date of the position and of t = 0.
    n_ccd, n_transits, n_visibility_periods : int (n,)
        AL CCD observations used, FoV transits with at least one, visibility periods.
    time_span_yr : (n,)
        From the first to the last observation used.
    excess_noise_mas : (n,)
        AGIS's excess source noise, mas, added in quadrature to every observation.
    model : str
        '5p' or '6p'.
    pseudocolour : (n,) or None
        nu of the 6x6 solution without astrometric prior (nm^-1); None for 5p.
    pseudocolour_error : (n,) or None
        Its standard error (nm^-1); None for 5p.

    Examples
    --------
    >>> from importlib.resources import files
    >>> data = files('mcsweep') / 'data' / 'epoch_astrometry'
    >>> from mcsweep.tables import read_table
    >>> from mcsweep.astrometry.epoch_astrometry import ccd_observations
    >>> table = read_table(data / 'sample_epoch_astrometry.parquet')
    >>> obs = ccd_observations(table)
    >>> from mcsweep.astrometry.source_update import source_normals
    >>> # the reference epoch: each source's mean epoch
    >>> normals = source_normals(obs, reference_epoch_jd=None)
    >>> normals.model, normals.n_visibility_periods[:3].tolist()
    ('5p', [50, 37, 31])
    """

    source_id: np.ndarray
    N: np.ndarray
    b: np.ndarray
    reference_epoch_jd: np.ndarray
    n_ccd: np.ndarray
    n_transits: np.ndarray
    n_visibility_periods: np.ndarray
    time_span_yr: np.ndarray
    excess_noise_mas: np.ndarray
    model: str
    pseudocolour: np.ndarray | None = None
    pseudocolour_error: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.source_id.size)


def _segments(sorted_keys: np.ndarray) -> np.ndarray:
    """Start index of each run of equal keys."""
    return np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]]) if sorted_keys.size else \
        np.empty(0, np.int64)


def visibility_periods(source_index, tcb_jd, n_sources: int) -> np.ndarray:
    """Visibility periods per source from its FoV transits' times (any order): groups of
    transits more than :data:`VISIBILITY_GAP_DAYS` apart.

    ``source_index`` (int, one per transit) numbers the sources 0..n_sources-1."""
    order = np.lexsort((tcb_jd, source_index))
    src, t = np.asarray(source_index)[order], np.asarray(tcb_jd)[order]
    new_period = np.r_[True, (src[1:] != src[:-1]) | (np.diff(t) > VISIBILITY_GAP_DAYS)] if src.size else \
        np.zeros(0, bool)
    return np.bincount(src[new_period], minlength=n_sources)


def _transit_counts(transit, tcb_jd, starts) -> tuple[np.ndarray, np.ndarray]:
    """(FoV transits, visibility periods) per source from its observations' times.

    A transit is a row of the file (its CCDs are consecutive within the source's block): two
    rows of one source may share their CCD times (seen in the DR4 sample: two windows read
    at once), and both count, as AGIS counts both rows' observations.
    """
    n = starts.size
    src = np.repeat(np.arange(n), np.diff(np.r_[starts, transit.size]))
    first = np.r_[True, (transit[1:] != transit[:-1]) | (src[1:] != src[:-1])]
    src_tr = src[first]
    t_tr = np.minimum.reduceat(tcb_jd, np.flatnonzero(first))
    return np.bincount(src_tr, minlength=n), visibility_periods(src_tr, t_tr, n)


def source_normals(obs: CcdObservations, *, model: str = "5p",
                   reference_epoch_jd: float | None = DR4_REFERENCE_EPOCH_JD) -> SourceNormals:
    """Weighted normal equations of every source in ``obs`` (module notes).

    Parameters
    ----------
    obs : CcdObservations
        Grouped by source, a transit's CCDs together (as
        :func:`~.epoch_astrometry.ccd_observations` returns them).
    model : {'5p', '6p'}
        Five parameters, or six with the pseudocolour nu eliminated (module notes).
    reference_epoch_jd : float or None
        TCB Julian date of the reference epoch; None: each source's mean epoch of
        observation (the paper's choice, Sect. 2.1).

    Returns
    -------
    SourceNormals
        One row per source, in increasing ``source_id``.

    Examples
    --------
    >>> from importlib.resources import files
    >>> data = files('mcsweep') / 'data' / 'epoch_astrometry'
    >>> from mcsweep.tables import read_table
    >>> from mcsweep.astrometry.epoch_astrometry import ccd_observations
    >>> table = read_table(data / 'sample_epoch_astrometry.parquet')
    >>> obs = ccd_observations(table)
    >>> from mcsweep.astrometry.source_update import source_normals
    >>> normals = source_normals(obs)
    >>> normals.N.shape, normals.n_transits[:3].tolist()
    ((10, 5, 5), [147, 103, 56])
    """
    check_model(model)
    if model == "6p" and obs.colour_factor_al is None:
        raise UserInputError("the six-parameter model needs colour_factor_al; expected it in the epoch file "
                             "(or use --model 5p)")
    sid = obs.source_id
    starts = _segments(sid)
    n = starts.size
    counts = np.diff(np.r_[starts, sid.size])
    if reference_epoch_jd is None:
        epoch = np.add.reduceat(obs.tcb_jd, starts) / counts if n else np.empty(0)
    else:
        epoch = np.full(n, float(reference_epoch_jd))
    t_yr = (obs.tcb_jd - np.repeat(epoch, counts)) / JULIAN_YEAR_DAYS
    theta = np.deg2rad(obs.scan_angle_deg)
    sw = 1.0 / np.sqrt(obs.sigma_al_mas ** 2 + obs.excess_noise_mas ** 2)
    s, c = np.sin(theta) * sw, np.cos(theta) * sw
    cols = [s, c, obs.parallax_factor_al * sw, t_yr * s, t_yr * c]
    if model == "6p":
        cols.append(obs.colour_factor_al * COLOUR_FACTOR_SCALE * sw)
    h = obs.centroid_al_mas * sw
    p = len(cols)
    N = np.empty((n, p, p))
    b = np.empty((n, p))
    if n:
        for i in range(p):
            b[:, i] = np.add.reduceat(cols[i] * h, starts)
            for j in range(i + 1):
                N[:, i, j] = N[:, j, i] = np.add.reduceat(cols[i] * cols[j], starts)
    nu = nu_err = None
    if model == "6p":
        N[:, 5, 5] += 1.0 / PSEUDOCOLOUR_PRIOR_PER_NM ** 2
        nu, nu_err = _pseudocolour(N, b)
        # nu eliminated: the marginal normal equations of the five astrometric parameters.
        k = N[:, :5, 5] / N[:, 5, 5][:, None]
        b = b[:, :5] - k * b[:, 5][:, None]
        N = N[:, :5, :5] - k[:, :, None] * N[:, 5, :5][:, None, :]
        N = 0.5 * (N + np.swapaxes(N, 1, 2))
    n_tr, periods = _transit_counts(obs.transit, obs.tcb_jd, starts) if n else (np.empty(0, int),) * 2
    span = ((np.maximum.reduceat(obs.tcb_jd, starts) - np.minimum.reduceat(obs.tcb_jd, starts)) / JULIAN_YEAR_DAYS
            if n else np.empty(0))
    return SourceNormals(source_id=sid[starts], N=N, b=b, reference_epoch_jd=epoch, n_ccd=counts,
                         n_transits=n_tr, n_visibility_periods=periods, time_span_yr=span,
                         excess_noise_mas=obs.excess_noise_mas[starts] if n else np.empty(0), model=model,
                         pseudocolour=nu, pseudocolour_error=nu_err)


def _pseudocolour(N6, b6) -> tuple[np.ndarray, np.ndarray]:
    """nu and its formal error from the full 6x6 solution (NaN where singular)."""
    nu = np.full(N6.shape[0], np.nan)
    err = np.full(N6.shape[0], np.nan)
    if not N6.shape[0]:
        return nu, err
    try:
        cov = np.linalg.inv(N6)
    except np.linalg.LinAlgError:
        ok = np.linalg.matrix_rank(N6) == 6
        if ok.any():
            cov_ok = np.linalg.inv(N6[ok])
            nu[ok] = np.einsum("nj,nj->n", cov_ok[:, 5, :], b6[ok])
            err[ok] = np.sqrt(cov_ok[:, 5, 5])
        return nu, err
    return np.einsum("nj,nj->n", cov[:, 5, :], b6), np.sqrt(cov[:, 5, 5])
