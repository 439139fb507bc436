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

from ..renamed_names import old_names
from ..astrometry.design import JULIAN_YEAR_DAYS, PARAMETER_NAMES, design_matrix, reference_epoch, years_since
from ..astrometry.solve import normal_equations
from ..astrometry.source_update import visibility_periods
from ..errors import UserInputError
from ..scanning.ephemeris import gaia_position_au
from .. import tables as _tables
from ..tables import ASTROPY_FORMAT, detect_format, integer_ids
from .columns import finite_column, source_bp_rp
from .epochs import reference_epoch_jd
from .model import Prior
from .solutions import check_factor, solutions_table

__all__ = ["OBSERVATION_COLUMNS", "OPTIONAL_AC", "OBSERVER_COLUMNS", "SOURCE_COLUMNS", "read_table",
           "read_observations", "TransitTable", "pad_observations", "solve_observations", "write_solutions",
           "TableWriter",
           "detect_format"]

OBSERVATION_COLUMNS = ("source_id", "tcb_jd", "scan_angle_deg", "al_residual_mas", "al_sigma_mas")
OPTIONAL_AC = ("ac_residual_mas", "ac_sigma_mas")
OBSERVER_COLUMNS = ("obs_x_au", "obs_y_au", "obs_z_au")
SOURCE_COLUMNS = ("source_id", "ra", "dec", "phot_g_mean_mag")


def read_table(path, what: str = "") -> pd.DataFrame:
    """A table file (format from the suffix) as a DataFrame, identifiers exact; UserInputError if unreadable."""
    return _tables.read_table(path, what=what).frame()


def _numeric(df: pd.DataFrame, cols, source: str) -> dict[str, np.ndarray]:
    return {c: finite_column(df[c], c, source) for c in cols}


def _require_columns(df, cols, source, what):
    lower = {str(c).lower(): c for c in df.columns}
    missing = [c for c in cols if c not in lower]
    if missing:
        raise UserInputError(f"{source}: columns {list(df.columns)[:12]} lack {missing}; expected {what}")
    return df.rename(columns={lower[c]: c for c in cols})


class TransitTable(dict):
    """A user's table of FoV transits, checked: its columns as plain arrays (dict of name ->
    ndarray), the transits sorted."""


def read_observations(obs_path, sources_path=None) -> TransitTable:
    """Read and check a table of FoV transits and its sources.

    Parameters
    ----------
    obs_path : str or path-like
        One row per FoV transit (columns of the module notes; any table format).
    sources_path : str or path-like, optional
        ``source_id, ra, dec, phot_g_mean_mag`` per source, if not in ``obs_path``.

    Returns
    -------
    TransitTable
        The checked columns, transits sorted by source and time.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from mcsweep.prior.example import simulate_example
    >>> obs, src = simulate_example(5, seed=1)
    >>> tmp = Path(tempfile.mkdtemp())
    >>> obs.to_csv(tmp / 'obs.csv', index=False)
    >>> src.to_csv(tmp / 'sources.csv', index=False)
    >>> from mcsweep.prior.observations import read_observations
    >>> table = read_observations(tmp / 'obs.csv', tmp / 'sources.csv')
    >>> type(table).__name__, 'al_residual_mas' in table
    ('TransitTable', True)
    """
    obs = read_table(obs_path, "observations")
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
        src = read_table(sources_path, "--sources")
        sname = Path(sources_path).name
        src = _require_columns(src, SOURCE_COLUMNS, sname, "source_id, ra, dec [deg] and phot_g_mean_mag")
        sid = pd.Series(integer_ids(src["source_id"].to_numpy(), "source_id", sname))
        if sid.duplicated().any():
            raise UserInputError(f"{sname}: source_id {sid[sid.duplicated()].iloc[0]} appears twice; expected one "
                                 "row per source")
    else:
        src = _require_columns(obs, SOURCE_COLUMNS, name, "source_id, ra, dec [deg] and phot_g_mean_mag "
                               "(or a separate --sources table)")
        colour = [c for c in obs.columns if str(c).lower() in ("bp_rp", "phot_bp_mean_mag", "phot_rp_mean_mag")]
        src = src[list(SOURCE_COLUMNS) + colour]
        src = src[~pd.Series(integer_ids(src["source_id"].to_numpy(), "source_id", name)).duplicated().to_numpy()]
        sname = name
    vals = _numeric(obs, cols[1:], name)
    svals = _numeric(src, SOURCE_COLUMNS[1:], sname)
    svals["bp_rp"] = source_bp_rp(src, sname)
    for key, ok, accepted in (("al_sigma_mas", vals["al_sigma_mas"] > 0, "positive uncertainties in mas"),
                              ("ac_sigma_mas", vals.get("ac_sigma_mas", np.ones(1)) > 0, "positive uncertainties in mas")):
        if not ok.all():
            raise UserInputError(f"{name}: column {key} has {int((~ok).sum())} value(s) <= 0; expected {accepted}")
    if np.any(np.abs(svals["dec"]) > 90):
        raise UserInputError(f"{sname}: column dec has values beyond +-90; expected degrees")
    # Gaia source_ids exceed 2**53: never through float64 (mcsweep.tables.ids).
    ids = integer_ids(src["source_id"].to_numpy(), "source_id", sname)
    obs_ids = integer_ids(obs["source_id"].to_numpy(), "source_id", name)
    order = np.argsort(ids, kind="stable")
    ids_sorted = ids[order]
    where = np.searchsorted(ids_sorted, obs_ids)
    found = (where < ids_sorted.size) & (ids_sorted[np.minimum(where, ids_sorted.size - 1)] == obs_ids)
    if not found.all():
        raise UserInputError(f"{name}: source_id {obs_ids[~found][0]} has no row in {sname}; expected "
                             "ra, dec and phot_g_mean_mag for every observed source")
    # Transits sorted by (source, time); sources in increasing source_id.
    sort = np.lexsort((vals["tcb_jd"], obs_ids))
    out = TransitTable({k: v[sort] for k, v in vals.items()})
    out["source_id"] = obs_ids[sort]
    used = np.unique(out["source_id"])
    pick = order[np.searchsorted(ids_sorted, used)]
    for k in ("ra", "dec", "phot_g_mean_mag", "bp_rp"):
        out[f"source_{k}"] = svals[k][pick]
    out["source_ids"] = used
    out["has_ac"] = has_ac
    out["has_observer"] = has_obs
    return out


def pad_observations(obs: TransitTable) -> dict[str, np.ndarray]:
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
    return np.full(padded["mask"].shape[0], reference_epoch_jd(setting))


def solve_observations(obs: TransitTable, prior: Prior, *, factor: float = 1.0, confidence: float | None = None,
                       reference_epoch: str = "star_mean") -> pd.DataFrame:
    """One row per source: prior, two-parameter and no-prior solutions, the P ellipse, which to use.

    Parameters
    ----------
    obs : TransitTable
        From :func:`read_observations`.
    prior : Prior
        sigma_plx = ``factor`` x sigma_F90 at the source's (l, b, G) and, for a prior with
        a colour axis, BP-RP; sigma_mu = R sigma_plx; centred on the prior's mean where it
        has one (:func:`mcsweep.prior.solutions.solutions_table`).
    factor : float, keyword-only
        K (Sect. 3.3: up to ~10 keeps the errors and gives conservative uncertainties).
    confidence : float, keyword-only
        P of the ellipse; default the prior's own P.
    reference_epoch : str, keyword-only
        'star_mean' (Sect. 2.1: mean epoch of each source's transits), or a date
        (ISO, 'J2017.5' or 2017.5, TCB).

    Returns
    -------
    pandas.DataFrame
        The columns of :func:`mcsweep.prior.solutions.solutions_table`.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from mcsweep.prior.example import simulate_example
    >>> obs, src = simulate_example(5, seed=1)
    >>> tmp = Path(tempfile.mkdtemp())
    >>> obs.to_csv(tmp / 'obs.csv', index=False)
    >>> src.to_csv(tmp / 'sources.csv', index=False)
    >>> from mcsweep.prior import Prior
    >>> from mcsweep.prior.observations import (
    ...     read_observations, solve_observations)
    >>> table = read_observations(tmp / 'obs.csv', tmp / 'sources.csv')
    >>> sol = solve_observations(table, Prior.paper())
    >>> len(sol) == len(src), 'ellipse_semi_major_mas' in sol.columns
    (True, True)
    """
    check_factor(factor)
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
    tcb = padded["tcb_jd"]
    span = (np.nanmax(tcb, axis=1) - np.nanmin(tcb, axis=1)) / JULIAN_YEAR_DAYS
    return solutions_table(obs["source_ids"], ra, dec, g, obs.get("source_bp_rp"), N0, b0,
                           n_transits=padded["counts"], reference_epoch_jd=epoch,
                           n_visibility_periods=_visibility_periods(obs), time_span_yr=span, prior=prior,
                           factor=factor, confidence=confidence)


def _visibility_periods(obs: TransitTable) -> np.ndarray:
    """Visibility periods per source: its transits in groups more than 4 days apart."""
    src = np.searchsorted(obs["source_ids"], obs["source_id"])
    return visibility_periods(src, obs["tcb_jd"], obs["source_ids"].size)


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
        # path is the command's own temporary file (made empty by mkstemp): overwrite it.
        t.write(path, format=ASTROPY_FORMAT[fmt], overwrite=True)


class TableWriter:
    """Writes a solutions table given in pieces: CSV and Parquet streamed piece by piece (flat
    memory), the astropy formats (FITS, VOTable, ECSV) gathered and written on closing."""

    def __init__(self, path, fmt: str):
        self.path, self.fmt = Path(path), fmt
        self._pieces: list[pd.DataFrame] = []
        self._parquet = None
        self._csv = None
        self._columns = None

    def __enter__(self):
        return self

    def write(self, table: pd.DataFrame) -> None:
        if self._columns is None:
            self._columns = list(table.columns)
        if self.fmt == "csv":
            if self._csv is None:
                self._csv = open(self.path, "w", newline="")
            table.to_csv(self._csv, index=False, header=self._csv.tell() == 0)
        elif self.fmt == "parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            batch = pa.Table.from_pandas(table, preserve_index=False)
            if self._parquet is None:
                self._parquet = pq.ParquetWriter(self.path, batch.schema)
            self._parquet.write_table(batch.cast(self._parquet.schema))
        else:
            self._pieces.append(table)

    def __exit__(self, exc_type, exc, tb):
        if self._csv is not None:
            self._csv.close()
        if self._parquet is not None:
            self._parquet.close()
        if exc_type is not None:
            return False
        if self.fmt in ("csv", "parquet"):
            if self._columns is None:  # no source at all: an empty table with no columns
                write_solutions(pd.DataFrame(), self.path, self.fmt)
        else:
            write_solutions(pd.concat(self._pieces, ignore_index=True) if self._pieces else pd.DataFrame(),
                            self.path, self.fmt)
        return False


# The parameter order of the astrometry stage is the one used above.
assert tuple(n.split("_")[0] for n in PARAMETER_NAMES) == ("dalpha", "ddelta", "parallax", "pmra", "pmdec")


#: Renamed so that "observations" is only the config group and users' files of transits.
__getattr__ = old_names(__name__, {"Observations": "TransitTable"})
