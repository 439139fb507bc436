"""Checks of users' numbers: numeric columns of their tables, units of their angles and magnitudes."""

from __future__ import annotations

import numpy as np
from astropy import units as u

from ..errors import UserInputError

__all__ = ["finite_column", "unit_scale", "read_run_table"]

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
