"""Checks of users' numbers (numeric columns of their tables, units of their angles and
magnitudes) and the names of the columns the prior's commands add to them."""

from __future__ import annotations

import numpy as np
from astropy import units as u

from ..errors import UserInputError

__all__ = ["finite_column", "unit_scale", "read_run_table", "source_bp_rp", "PRIOR_MEAN_COLUMNS"]

#: A mean-centred prior's centre, in the tables of ``mcsweep-prior annotate`` and ``solve``:
#: parallax [mas], pmra* and pmdec [mas/yr, ICRS].
PRIOR_MEAN_COLUMNS = ("prior_mean_parallax_mas", "prior_mean_pmra_mas_yr", "prior_mean_pmdec_mas_yr")

_EXPECTED = {"angle": "an angle (deg)", "mag": "magnitudes (mag or plain numbers)"}


def read_run_table(path, columns, needed_for: str, numeric=()):
    """A CSV table of a sweep's run directory with at least ``columns``, or a one-line
    :class:`UserInputError`: the file is missing (``needed_for`` says which runs write it), is
    not CSV, lacks columns, or has non-numbers in the ``numeric`` ones (NaN allowed), which
    are returned as float64."""
    from pathlib import Path

    from ..tables import read_table

    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"run directory {path.parent} has no {path.name}; expected it in a sweep {needed_for}")
    table = read_table(path, fmt="csv", what="run table").frame()
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise UserInputError(f"{path} lacks the columns {missing}; expected {', '.join(columns)}")
    for c in numeric:
        try:
            table[c] = table[c].to_numpy(dtype=float)
        except (TypeError, ValueError):
            raise UserInputError(f"{path}: column {c} has non-numeric values; expected numbers (NaN where "
                                 "undetermined)") from None
    return table


def finite_column(values, name: str, source: str, where: str = "") -> np.ndarray:
    """``values`` as float64, or a one-line :class:`UserInputError` naming the column.

    ``where`` qualifies the row number in the message (e.g. ``" of its batch"`` when a
    large file is read in batches).
    """
    try:
        v = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise UserInputError(f"{source}: column {name} has non-numeric values; expected numbers") from None
    bad = ~np.isfinite(v)
    if bad.any():
        raise UserInputError(f"{source}: column {name} has {int(bad.sum())} NaN or infinite value(s) "
                             f"(first at row {int(np.argmax(bad))}{where}); expected finite values in every row")
    return v


def unit_scale(unit, kind: str, what: str) -> float:
    """Factor converting values in ``unit`` to degrees (``kind='angle'``) or magnitudes (``'mag'``).

    ``unit`` is an astropy unit or its string (a file's column metadata); ``None`` or an
    empty string means plain numbers (factor 1). Anything else, including an unparsable
    string, is a one-line :class:`UserInputError` naming ``what`` and the unit.
    """
    if unit is None or str(unit) in ("", "None"):
        return 1.0
    try:
        unit = u.Unit(unit)
        if kind == "angle":
            return float(unit.to(u.deg))
        if unit in (u.mag, u.dimensionless_unscaled):
            return 1.0
    except (u.UnitConversionError, ValueError, TypeError):
        pass
    raise UserInputError(f"{what} in {unit} is not accepted; expected {_EXPECTED[kind]}")


def source_bp_rp(src, source: str) -> np.ndarray:
    """BP-RP per row of the DataFrame ``src`` from ``bp_rp`` or ``phot_bp_mean_mag -
    phot_rp_mean_mag`` (names matched case-insensitively); NaN where unknown or without
    those columns; a one-line :class:`~mcsweep.errors.UserInputError` for non-numbers."""
    import pandas as pd

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
