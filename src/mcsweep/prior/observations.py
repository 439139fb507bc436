"""Solve a user's own few-transit observations with the prior (``mcsweep-prior solve``).

Input: one row per field-of-view transit (column names below), and each source's
reference position and G in the same table or a second one. Everything numerical goes
through the astrometry stage: the Eq. 1 design matrix
(:func:`mcsweep.astrometry.design.design_matrix`), the normal equations and the three
solutions (:func:`~mcsweep.astrometry.solve.solve_with_prior` with sigma_plx = K
sigma_F90 and sigma_mu = R sigma_plx, Eq. 18; the two-parameter solution; the
no-prior solution with its conditioning flag) and the P confidence ellipse
(:mod:`mcsweep.astrometry.confidence`).

Observation columns (units in the names):

=====================  ==============================================================
``source_id``          integer identifier
``tcb_jd``             transit time at Gaia, Julian date in TCB
``scan_angle_deg``     scan position angle psi (0 = local north, 90 = east; the
                       direction in which the field of view moves across the star)
``al_residual_mas``    along-scan residual: observed minus computed from the
                       reference position, mas
``al_sigma_mas``       its uncertainty, mas
``ac_residual_mas``    optional, across-scan residual (direction (-cos psi, sin psi))
``ac_sigma_mas``       optional, its uncertainty
``obs_x_au`` .. ``_z`` optional observer BCRS position, au (default: Gaia's, from
                       :func:`mcsweep.scanning.ephemeris.gaia_position_au`)
=====================  ==============================================================

Source columns: ``source_id``, ``ra``, ``dec`` [deg, ICRS reference position] and
``phot_g_mean_mag``; optionally the colour, ``bp_rp`` or ``phot_bp_mean_mag`` and
``phot_rp_mean_mag`` (used by a prior with a colour axis; empty or NaN: the colour-blind
prior of the same run).

A mean-centred prior (:attr:`Prior.has_mean`) enters as the prior mean x_p of Eqs. 11-12:
the right-hand side gains ``N_p x_p`` with x_p = (0, 0, mean parallax, mean pmra*, mean
pmdec) of the source's cell; the output then lists that centre
(``prior_mean_parallax_mas``, ``prior_mean_pmra_mas_yr``, ``prior_mean_pmdec_mas_yr``),
and for a prior with a colour axis the bin used (``prior_colour_bin``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..astrometry.confidence import check_probability, ellipse_position_angle_deg, ellipse_semi_axes
from ..astrometry.design import PARAMETER_NAMES, design_matrix, reference_epoch, years_since
from ..astrometry.solve import normal_equations, solve_no_prior, solve_position_only, solve_with_prior
from ..errors import UserInputError
from ..scanning.ephemeris import gaia_position_au
from .annotate import ASTROPY_FORMAT, detect_format
from .columns import finite_column
from ..galactic import galactic_from_icrs
from .model import Prior

__all__ = ["OBSERVATION_COLUMNS", "OPTIONAL_AC", "OBSERVER_COLUMNS", "SOURCE_COLUMNS", "read_table",
           "read_observations", "Observations", "pad_observations", "solve_observations", "write_solutions",
           "detect_format"]

OBSERVATION_COLUMNS = ("source_id", "tcb_jd", "scan_angle_deg", "al_residual_mas", "al_sigma_mas")
OPTIONAL_AC = ("ac_residual_mas", "ac_sigma_mas")
OBSERVER_COLUMNS = ("obs_x_au", "obs_y_au", "obs_z_au")
SOURCE_COLUMNS = ("source_id", "ra", "dec", "phot_g_mean_mag")
_SHORT = ("dalpha_star", "ddelta", "parallax", "pmra", "pmdec")


def read_table(path) -> pd.DataFrame:
    """A table file (format from the suffix) as a DataFrame; UserInputError if unreadable."""
    path = Path(path)
    fmt = detect_format(path)
    if not path.is_file():
        raise UserInputError(f"{path} does not exist; expected a readable table file")
    try:
        if fmt == "csv":
            return pd.read_csv(path, comment="#")
        if fmt == "parquet":
            return pd.read_parquet(path)
        from astropy.table import Table

        return Table.read(path, format=ASTROPY_FORMAT[fmt]).to_pandas()
    except Exception as exc:  # readers raise many types; one line for the user
        raise UserInputError(f"{path.name}: cannot be read as {fmt} ({type(exc).__name__}); "
                             f"expected a {fmt} table") from None


def _source_colour(src: pd.DataFrame, source: str) -> np.ndarray:
    """BP-RP per source from ``bp_rp`` or ``phot_bp_mean_mag - phot_rp_mean_mag``; NaN where unknown."""
    lower = {str(c).lower(): c for c in src.columns}
    if "bp_rp" in lower:
        cols = [lower["bp_rp"]]
    elif "phot_bp_mean_mag" in lower and "phot_rp_mean_mag" in lower:
        cols = [lower["phot_bp_mean_mag"], lower["phot_rp_mean_mag"]]
    else:
        return np.full(len(src), np.nan)
    try:
        v = [pd.to_numeric(src[c], errors="raise").to_numpy(dtype=float) for c in cols]
    except (TypeError, ValueError):
        raise UserInputError(f"{source}: column {cols[0] if len(cols) == 1 else ' or '.join(cols)} has non-numeric "
                             "values; expected magnitudes (empty or NaN where unknown)") from None
    return v[0] if len(v) == 1 else v[0] - v[1]


def _numeric(df: pd.DataFrame, cols, source: str) -> dict[str, np.ndarray]:
    return {c: finite_column(df[c], c, source) for c in cols}


def _require_columns(df, cols, source, what):
    lower = {str(c).lower(): c for c in df.columns}
    missing = [c for c in cols if c not in lower]
    if missing:
        raise UserInputError(f"{source}: columns {list(df.columns)[:12]} lack {missing}; expected {what}")
    return df.rename(columns={lower[c]: c for c in cols})


class Observations(dict):
    """Checked input columns as plain arrays (dict of name -> ndarray), transits sorted."""


def read_observations(obs_path, sources_path=None) -> Observations:
    """Read and check the observation table (and the sources table, if separate)."""
    obs = read_table(obs_path)
    name = Path(obs_path).name
    obs = _require_columns(obs, OBSERVATION_COLUMNS, name,
                           "source_id, tcb_jd, scan_angle_deg, al_residual_mas, al_sigma_mas")
    lower = {str(c).lower() for c in obs.columns}
    has_ac = all(c in lower for c in OPTIONAL_AC)
    if any(c in lower for c in OPTIONAL_AC) and not has_ac:
        raise UserInputError(f"{name}: has only one of {OPTIONAL_AC}; expected both or neither")
    has_obs = all(c in lower for c in OBSERVER_COLUMNS)
    if any(c in lower for c in OBSERVER_COLUMNS) and not has_obs:
        raise UserInputError(f"{name}: has only some of {OBSERVER_COLUMNS}; expected all three or none")
    cols = OBSERVATION_COLUMNS + (OPTIONAL_AC if has_ac else ()) + (OBSERVER_COLUMNS if has_obs else ())
    obs = _require_columns(obs, cols, name, str(cols))
    if sources_path is not None:
        src = read_table(sources_path)
        sname = Path(sources_path).name
        src = _require_columns(src, SOURCE_COLUMNS, sname, "source_id, ra, dec [deg] and phot_g_mean_mag")
        if src["source_id"].duplicated().any():
            dup = src.loc[src["source_id"].duplicated(), "source_id"].iloc[0]
            raise UserInputError(f"{sname}: source_id {dup} appears twice; expected one row per source")
    else:
        src = _require_columns(obs, SOURCE_COLUMNS, name, "source_id, ra, dec [deg] and phot_g_mean_mag "
                               "(or a separate --sources table)")
        colour = [c for c in obs.columns if str(c).lower() in ("bp_rp", "phot_bp_mean_mag", "phot_rp_mean_mag")]
        src = src[list(SOURCE_COLUMNS) + colour].drop_duplicates("source_id")
        sname = name
    vals = _numeric(obs, cols, name)
    svals = _numeric(src, SOURCE_COLUMNS, sname)
    svals["bp_rp"] = _source_colour(src, sname)
    for key, ok, accepted in (("al_sigma_mas", vals["al_sigma_mas"] > 0, "positive uncertainties in mas"),
                              ("ac_sigma_mas", vals.get("ac_sigma_mas", np.ones(1)) > 0, "positive uncertainties in mas")):
        if not ok.all():
            raise UserInputError(f"{name}: column {key} has {int((~ok).sum())} value(s) <= 0; expected {accepted}")
    if np.any(np.abs(svals["dec"]) > 90):
        raise UserInputError(f"{sname}: column dec has values beyond +-90; expected degrees")
    ids = svals["source_id"].astype(np.int64)
    obs_ids = vals["source_id"].astype(np.int64)
    order = np.argsort(ids, kind="stable")
    ids_sorted = ids[order]
    where = np.searchsorted(ids_sorted, obs_ids)
    found = (where < ids_sorted.size) & (ids_sorted[np.minimum(where, ids_sorted.size - 1)] == obs_ids)
    if not found.all():
        raise UserInputError(f"{name}: source_id {obs_ids[~found][0]} has no row in {sname}; expected "
                             "ra, dec and phot_g_mean_mag for every observed source")
    # Transits sorted by (source, time); sources in increasing source_id.
    sort = np.lexsort((vals["tcb_jd"], obs_ids))
    out = Observations({k: v[sort] for k, v in vals.items()})
    out["source_id"] = obs_ids[sort]
    used = np.unique(out["source_id"])
    pick = order[np.searchsorted(ids_sorted, used)]
    for k in ("ra", "dec", "phot_g_mean_mag", "bp_rp"):
        out[f"source_{k}"] = svals[k][pick]
    out["source_ids"] = used
    out["has_ac"] = has_ac
    out["has_observer"] = has_obs
    return out


def pad_observations(obs: Observations) -> dict[str, np.ndarray]:
    """Per-source padded arrays (n sources x k = most transits of a source) and the mask."""
    sid = obs["source_id"]
    n_tr = sid.size
    starts = np.flatnonzero(np.r_[True, sid[1:] != sid[:-1]])
    counts = np.diff(np.r_[starts, n_tr])
    row = np.repeat(np.arange(starts.size), counts)
    col = np.arange(n_tr) - starts[row]
    n, k = starts.size, int(counts.max())
    mask = np.zeros((n, k), dtype=bool)
    mask[row, col] = True

    def pad(v, fill=np.nan):
        a = np.full((n, k) + v.shape[1:], fill)
        a[row, col] = v
        return a

    obs_au = (np.stack([obs[c] for c in OBSERVER_COLUMNS], axis=-1) if obs["has_observer"]
              else gaia_position_au(obs["tcb_jd"]))
    out = {"mask": mask, "counts": counts, "tcb_jd": pad(obs["tcb_jd"]), "psi_deg": pad(obs["scan_angle_deg"]),
           "obs_au": pad(obs_au), "al_res": pad(obs["al_residual_mas"], 0.0), "al_sig": pad(obs["al_sigma_mas"], 1.0)}
    if obs["has_ac"]:
        out["ac_res"] = pad(obs["ac_residual_mas"], 0.0)
        out["ac_sig"] = pad(obs["ac_sigma_mas"], 1.0)
    return out


def _epochs(setting: str, padded) -> np.ndarray:
    if setting == "star_mean":
        return reference_epoch(padded["tcb_jd"], padded["mask"])
    from astropy.time import Time

    try:
        jd = float(Time(setting, scale="tcb").jd)
    except (ValueError, TypeError):
        raise UserInputError(f"--reference-epoch {setting!r} is not accepted; expected 'star_mean' or an "
                             "ISO date (TCB) such as '2015-01-01T00:00:00'") from None
    return np.full(padded["mask"].shape[0], jd)


def solve_observations(obs: Observations, prior: Prior, *, factor: float = 1.0, confidence: float | None = None,
                       reference_epoch: str = "star_mean") -> pd.DataFrame:
    """One row per source: prior, two-parameter and no-prior solutions, the P ellipse.

    Parameters
    ----------
    obs : Observations
        From :func:`read_observations`.
    prior : Prior
        sigma_plx = ``factor`` x sigma_F90 at the source's (l, b, G) and, for a prior with
        a colour axis, BP-RP; sigma_mu = R sigma_plx; centred on the prior's mean where it
        has one (module notes).
    factor : float, keyword-only
        K (Sect. 3.3: up to ~10 keeps the errors and gives conservative uncertainties).
    confidence : float, keyword-only
        P of the ellipse; default the prior's own P.
    reference_epoch : str, keyword-only
        'star_mean' (Sect. 2.1: mean epoch of each source's transits) or an ISO date (TCB).
    """
    if not (np.isscalar(factor) and factor > 0 and np.isfinite(factor)):
        raise UserInputError(f"--factor {factor!r} is not accepted; expected a positive finite number")
    p = check_probability(prior.confidence if confidence is None else confidence)
    padded = pad_observations(obs)
    mask = padded["mask"]
    epoch = _epochs(reference_epoch, padded)
    t_yr = years_since(np.where(mask, padded["tcb_jd"], epoch[:, None]), epoch)
    ra, dec, g = obs["source_ra"], obs["source_dec"], obs["source_phot_g_mean_mag"]
    has_ac = obs["has_ac"]
    A = design_matrix(ra, dec, t_yr, padded["psi_deg"], np.nan_to_num(padded["obs_au"]),
                      sigma_al_mas=padded["al_sig"], sigma_ac_mas=padded["ac_sig"] if has_ac else None, mask=mask)
    h = padded["al_res"] / padded["al_sig"]
    if has_ac:
        h = np.concatenate([h, padded["ac_res"] / padded["ac_sig"]], axis=1)
    h = np.where(np.concatenate([mask, mask], axis=1) if has_ac else mask, h, 0.0)
    N0, b0 = normal_equations(A, h)
    l_deg, b_deg = galactic_from_icrs(ra, dec)
    bp_rp = obs.get("source_bp_rp") if prior.has_colour else None
    sigma_plx = factor * prior.sigma_parallax_mas(l_deg, b_deg, g, bp_rp)
    centre = None
    if prior.has_mean:
        m_plx = prior.mean_parallax_mas(l_deg, b_deg, g, bp_rp)
        m_pmra, m_pmdec = prior.mean_pm_masyr(l_deg, b_deg, g, bp_rp)
        centre = np.stack([np.zeros_like(m_plx), np.zeros_like(m_plx), m_plx, m_pmra, m_pmdec], axis=-1)
    with_prior = solve_with_prior(N0, b0, sigma_plx, prior.ratio_R, prior_mean=centre)
    two = solve_position_only(N0, b0)
    free = solve_no_prior(N0, b0)
    a_mas, b_mas = ellipse_semi_axes(with_prior.position_cov, p)

    out = {"source_id": obs["source_ids"], "ra": ra, "dec": dec, "phot_g_mean_mag": g,
           "n_transits": padded["counts"], "reference_epoch_tcb_jd": epoch,
           "sigma_prior_parallax_mas": sigma_plx, "sigma_prior_pm_mas_yr": prior.ratio_R * sigma_plx,
           "prior_ok": with_prior.ok}
    if prior.has_colour:
        out["prior_colour_bin"] = prior.colour_bin_label(bp_rp)
    if centre is not None:
        out["prior_mean_parallax_mas"], out["prior_mean_pmra_mas_yr"], out["prior_mean_pmdec_mas_yr"] = centre[:, 2:].T
    units = dict(zip(_SHORT, ("mas", "mas", "mas", "mas_yr", "mas_yr")))
    for i, name in enumerate(_SHORT):
        out[f"{name}_{units[name]}"] = with_prior.x[:, i]
        out[f"{name}_error_{units[name]}"] = np.sqrt(with_prior.cov[:, i, i])
    for i in range(5):
        for j in range(i + 1, 5):
            with np.errstate(invalid="ignore", divide="ignore"):
                out[f"{_SHORT[i]}_{_SHORT[j]}_corr"] = with_prior.cov[:, i, j] / np.sqrt(
                    with_prior.cov[:, i, i] * with_prior.cov[:, j, j])
    out["confidence"] = np.full(len(ra), p)
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
        out[f"no_prior_{name}_{units[name]}"] = free.x[:, i]
        out[f"no_prior_{name}_error_{units[name]}"] = np.sqrt(free.cov[:, i, i])
    return pd.DataFrame(out)


def write_solutions(table: pd.DataFrame, path, fmt: str) -> None:
    """Write the per-source table in ``fmt`` (csv, parquet, or an astropy format with units)."""
    path = Path(path)
    if fmt == "csv":
        table.to_csv(path, index=False)
    elif fmt == "parquet":
        table.to_parquet(path, index=False)
    else:
        from astropy.table import Table

        t = Table.from_pandas(table)
        for c in t.colnames:
            if c.endswith("_mas_yr"):
                t[c].unit = "mas / yr"
            elif c.endswith("_mas"):
                t[c].unit = "mas"
            elif c.endswith("_deg") or c in ("ra", "dec"):
                t[c].unit = "deg"
        t.write(path, format=ASTROPY_FORMAT[fmt])


# The parameter order of the astrometry stage is the one used above.
assert tuple(n.split("_")[0] for n in PARAMETER_NAMES) == ("dalpha", "ddelta", "parallax", "pmra", "pmdec")
