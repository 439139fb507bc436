"""Checks of the numeric columns of users' tables (catalogues to annotate, observations to solve)."""

from __future__ import annotations

import numpy as np

from ..errors import UserInputError

__all__ = ["finite_column"]


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
