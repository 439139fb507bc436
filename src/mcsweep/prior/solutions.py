"""A source's three solutions from its normal equations, its P ellipse, and which to use.

Shared by ``mcsweep-prior solve`` on per-transit observations (``mcsweep.prior.observations``) and on
Gaia epoch astrometry (:mod:`.epoch_solve`): given each source's normal equations
``N0 x = b0`` (Eqs. 2-3) it gives the solution with the prior (sigma_plx = K sigma_F90 at
the source's l, b, G and colour, sigma_mu = R sigma_plx, Eq. 18, centred on the prior's
mean where it has one, Eqs. 11-12), the two-parameter solution, the five-parameter
solution without prior, and the P confidence ellipse of the prior solution's position
(Sect. 2.4), as one row per source with the same columns for both inputs.

Which solution to use (columns ``solution`` and ``solution_reason``). The paper's rule
(Sect. 1 and the conclusions): a prior only where a five-parameter solution cannot be
obtained from the data alone, never where it can, because a prior biases parallax and
proper motion. A source gets ``five_parameter`` when all hold:

* the no-prior normal matrix is well conditioned (``no_prior_ok``: condition number at most
  ``mcsweep.astrometry.solve.DEFAULT_MAX_CONDITION``);
* its observations fall in at least ``MIN_VISIBILITY_PERIODS`` visibility periods
  (groups more than 4 days apart), the condition under which Gaia DR2 published five-parameter
  solutions (Lindegren et al. 2018, A&A 616, A2: visibility_periods_used >= 6);
* they span at least ``MIN_SPAN_YR`` year, so that parallax and proper motion separate
  (the paper, Sect. 1: "the observations must span at least a whole year").

Otherwise ``prior``: use the position and its ellipse from the prior solution, and not its
parallax and proper motion (the paper's conclusions).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..astrometry.confidence import check_probability, ellipse_position_angle_deg, ellipse_semi_axes
from ..astrometry.solve import solve_no_prior, solve_position_only, solve_with_prior
from ..errors import UserInputError
from ..galactic import galactic_from_icrs
from .columns import PRIOR_MEAN_COLUMNS
from .model import Prior

__all__ = ["MIN_VISIBILITY_PERIODS", "MIN_SPAN_YR", "check_factor", "solutions_table", "which_solution"]

#: Fewest visibility periods for a five-parameter solution without prior (Gaia DR2's rule).
MIN_VISIBILITY_PERIODS = 6
#: Shortest time span of the observations for one, in Julian years (the paper, Sect. 1).
MIN_SPAN_YR = 1.0
_SHORT = ("dalpha_star", "ddelta", "parallax", "pmra", "pmdec")
_UNITS = dict(zip(_SHORT, ("mas", "mas", "mas", "mas_yr", "mas_yr")))


def check_factor(factor) -> float:
    if not (np.isscalar(factor) and factor > 0 and np.isfinite(factor)):
        raise UserInputError(f"--factor {factor!r} is not accepted; expected a positive finite number")
    return float(factor)


def which_solution(no_prior_ok, n_visibility_periods, time_span_yr) -> tuple[np.ndarray, np.ndarray]:
    """(``solution``, ``solution_reason``) per source by the rule of the module notes."""
    ok = np.asarray(no_prior_ok, dtype=bool)
    vp = np.asarray(n_visibility_periods)
    span = np.asarray(time_span_yr, dtype=float)
    five = ok & (vp >= MIN_VISIBILITY_PERIODS) & (span >= MIN_SPAN_YR)
    reason = np.where(five, f"no-prior 5p determined: >= {MIN_VISIBILITY_PERIODS} visibility periods over "
                            f">= {MIN_SPAN_YR:g} yr", "")
    reason = np.where(~five & (span < MIN_SPAN_YR), np.char.add(np.char.add(
        "prior: observations span ", np.char.mod("%.2f", span)), f" yr < {MIN_SPAN_YR:g} yr"), reason)
    reason = np.where(~five & (span >= MIN_SPAN_YR) & (vp < MIN_VISIBILITY_PERIODS), np.char.add(np.char.add(
        "prior: ", vp.astype(str)), f" visibility period(s) < {MIN_VISIBILITY_PERIODS}"), reason)
    reason = np.where(~five & (span >= MIN_SPAN_YR) & (vp >= MIN_VISIBILITY_PERIODS) & ~ok,
                      "prior: no-prior normal matrix singular or ill-conditioned", reason)
    return np.where(five, "five_parameter", "prior"), reason


def solutions_table(source_id, ra_deg, dec_deg, g_mag, bp_rp, N0, b0, *, n_transits, reference_epoch_jd,
                    n_visibility_periods, time_span_yr, prior: Prior, factor: float = 1.0,
                    confidence: float | None = None) -> pd.DataFrame:
    """One row per source (module notes): prior, two-parameter and no-prior solutions, the P ellipse.

    Parameters
    ----------
    source_id : int64 array (n,)
        Source identifiers.
    ra_deg, dec_deg, g_mag, bp_rp : arrays (n,)
        The source's reference position (ICRS, deg), G and BP-RP (NaN: unknown; used only
        by a prior with a colour axis).
    N0, b0 : arrays (n, 5, 5), (n, 5)
        Normal equations in (mas, mas, mas, mas/yr, mas/yr).
    n_transits, reference_epoch_jd, n_visibility_periods, time_span_yr : arrays (n,)
        FoV transits, the reference epoch (TCB Julian date), visibility periods and the
        observations' time span (yr) of each source, reported with its solution.
    prior : Prior
        The prior (the paper's or a run's fit).
    factor : float
        K: the prior is K sigma_F90 (Sect. 3.3: up to ~10 keeps the errors).
    confidence : float or None
        P of the ellipse; default the prior's own P.

    Returns
    -------
    pandas.DataFrame
        One row per source, the columns of the module notes.

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.prior import Prior
    >>> from mcsweep.prior.solutions import solutions_table
    >>> N0, b0 = np.eye(5)[None] * 4.0, np.zeros((1, 5))
    >>> t = solutions_table(
    ...     [1], [150.0], [20.0], [15.0], [np.nan], N0, b0, n_transits=[3],
    ...     reference_epoch_jd=[2457389.0], n_visibility_periods=[2],
    ...     time_span_yr=[0.4], prior=Prior.paper())
    >>> # sigma_F90 of Eqs. 14-17 at the star, mas
    >>> round(float(t['sigma_prior_parallax_mas'][0]), 3)  # doctest: +FLOAT_CMP
    2.045
    """
    factor = check_factor(factor)
    p = check_probability(prior.confidence if confidence is None else confidence)
    ra, dec, g = (np.asarray(v, dtype=float) for v in (ra_deg, dec_deg, g_mag))
    l_deg, b_deg = galactic_from_icrs(ra, dec)
    colour = np.asarray(bp_rp, dtype=float) if prior.has_colour else None
    sigma_plx = factor * prior.sigma_parallax_mas(l_deg, b_deg, g, colour)
    centre = None
    if prior.has_mean:
        m_plx = prior.mean_parallax_mas(l_deg, b_deg, g, colour)
        m_pmra, m_pmdec = prior.mean_pm_masyr(l_deg, b_deg, g, colour)
        centre = np.stack([np.zeros_like(m_plx), np.zeros_like(m_plx), m_plx, m_pmra, m_pmdec], axis=-1)
    with_prior = solve_with_prior(N0, b0, sigma_plx, prior.ratio_R, prior_mean=centre)
    two = solve_position_only(N0, b0)
    free = solve_no_prior(N0, b0)
    a_mas, b_mas = ellipse_semi_axes(with_prior.position_cov, p)

    out = {"source_id": np.asarray(source_id, dtype=np.int64), "ra": ra, "dec": dec, "phot_g_mean_mag": g,
           "n_transits": np.asarray(n_transits), "reference_epoch_tcb_jd": np.asarray(reference_epoch_jd, float),
           "sigma_prior_parallax_mas": sigma_plx, "sigma_prior_pm_mas_yr": prior.ratio_R * sigma_plx,
           "prior_ok": with_prior.ok}
    if prior.has_colour:
        out["prior_colour_bin"] = prior.colour_bin_label(colour)
    if centre is not None:
        for name, values in zip(PRIOR_MEAN_COLUMNS, centre[:, 2:].T):
            out[name] = values
    for i, name in enumerate(_SHORT):
        out[f"{name}_{_UNITS[name]}"] = with_prior.x[:, i]
        out[f"{name}_error_{_UNITS[name]}"] = np.sqrt(with_prior.cov[:, i, i])
    for i in range(5):
        for j in range(i + 1, 5):
            with np.errstate(invalid="ignore", divide="ignore"):
                out[f"{_SHORT[i]}_{_SHORT[j]}_corr"] = with_prior.cov[:, i, j] / np.sqrt(
                    with_prior.cov[:, i, i] * with_prior.cov[:, j, j])
    out["confidence"] = np.full(ra.size, p)
    out["ellipse_semi_major_mas"] = a_mas
    out["ellipse_semi_minor_mas"] = b_mas
    out["ellipse_position_angle_deg"] = ellipse_position_angle_deg(with_prior.position_cov)
    out["two_param_ok"] = two.ok
    for i, name in enumerate(_SHORT[:2]):
        out[f"two_param_{name}_mas"] = two.x[:, i]
        out[f"two_param_{name}_error_mas"] = np.sqrt(two.cov[:, i, i])
    out["no_prior_ok"] = free.ok
    out["no_prior_condition"] = free.condition
    for i, name in enumerate(_SHORT):
        out[f"no_prior_{name}_{_UNITS[name]}"] = free.x[:, i]
        out[f"no_prior_{name}_error_{_UNITS[name]}"] = np.sqrt(free.cov[:, i, i])
    out["n_visibility_periods"] = np.asarray(n_visibility_periods)
    out["time_span_yr"] = np.asarray(time_span_yr, dtype=float)
    out["solution"], out["solution_reason"] = which_solution(free.ok, n_visibility_periods, time_span_yr)
    return pd.DataFrame(out)
