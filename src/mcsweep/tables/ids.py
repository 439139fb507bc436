"""Integer identifiers (Gaia ``source_id``) read exactly, or refused.

A Gaia ``source_id`` reaches ~7e18, beyond the 2**53 up to which float64 holds every
integer: ids read through float64 are rounded to multiples of up to 1024, and neighbouring
sources (e.g. 4472832130942575873 and 4472832130942575874) become one. So identifiers are
always int64, taken from integer columns or parsed from text, and a value that is not an
exact integer is refused rather than rounded.
"""

from __future__ import annotations

import numpy as np

from ..errors import UserInputError

__all__ = ["integer_ids", "FLOAT64_EXACT_LIMIT"]

#: Integers beyond this are not all representable in float64 (53-bit significand).
FLOAT64_EXACT_LIMIT = 2 ** 53


def _refuse(value, name: str, source: str):
    raise UserInputError(f"{source}: column {name} has the value {value!r}, which is not an exact integer "
                         "identifier; expected integers (write the column as integers or text, not as "
                         "floating point)")


def integer_ids(values, name: str, source: str) -> np.ndarray:
    """Read identifiers (Gaia ``source_id``) exactly as int64.

    Integer columns are taken as they are. Text is parsed digit by digit (so
    '4472832130942575873' stays exact). Floating-point values are accepted only if they are
    integers below 2**53, where float64 is exact; larger ones may already have been rounded
    when the file was written, so they are refused.

    Parameters
    ----------
    values : array_like
        The column: integers, text or floats.
    name : str
        The column's name, for messages.
    source : str
        The file's name, for messages.

    Returns
    -------
    ndarray of int64
        The identifiers.

    Raises
    ------
    mcsweep.errors.UserInputError
        One line naming the first value that is not an exact identifier.

    Examples
    --------
    >>> from mcsweep.tables import integer_ids
    >>> ids = ['4472832130942575873', '42']  # text, read digit by digit
    >>> integer_ids(ids, 'source_id', 'stars.csv')
    array([4472832130942575873,                  42])
    """
    arr = np.asarray(values)
    if arr.dtype.kind in "iu":
        if arr.dtype.kind == "u" and arr.size and arr.max() > np.iinfo(np.int64).max:
            _refuse(int(arr.max()), name, source)
        return arr.astype(np.int64)
    if arr.dtype.kind == "b":
        _refuse(arr.flat[0] if arr.size else None, name, source)
    if arr.dtype.kind == "f":
        if np.isnan(arr).any():
            raise UserInputError(f"{source}: column {name} has a missing value in row {int(np.argmax(np.isnan(arr)))}; "
                                 "expected an integer identifier in every row")
        bad = ~np.isfinite(arr) | (np.abs(arr) >= FLOAT64_EXACT_LIMIT) | (arr != np.round(arr))
        if bad.any():
            _refuse(float(arr[np.argmax(bad)]), name, source)
        return arr.astype(np.int64)
    text = np.char.strip(arr.astype(str))
    try:
        return text.astype(np.int64)
    except (ValueError, OverflowError):
        pass
    # Some values are not plain digits ('12.0', '1e3', junk): plain digits are parsed exactly,
    # the rest only where float64 holds them exactly.
    digits = np.char.isdigit(np.char.lstrip(text, "-+"))
    out = np.zeros(text.shape, dtype=np.int64)
    try:
        out[digits] = text[digits].astype(np.int64)
    except (ValueError, OverflowError):
        _refuse(str(text[digits][0]), name, source)
    rest = text[~digits]
    try:
        f = rest.astype(float)
    except ValueError:
        good = np.array([_is_float(t) for t in rest[:1000]])
        _refuse(str(rest[:1000][~good][0]) if (~good).any() else str(rest[0]), name, source)
    bad = ~np.isfinite(f) | (np.abs(f) >= FLOAT64_EXACT_LIMIT) | (f != np.round(f))
    if bad.any():
        _refuse(str(rest[np.argmax(bad)]), name, source)
    out[~digits] = f.astype(np.int64)
    return out


def _is_float(text) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
