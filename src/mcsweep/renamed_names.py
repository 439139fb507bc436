"""Python names that were renamed keep working under their old names, with a warning.

A public name is a contract, like a config key (:mod:`mcsweep.command.renamed`): scripts
written before a rename must still run. :func:`old_names` gives a module the
``__getattr__`` that answers an old name with the new name's object, and
:func:`renamed_keyword` a function the value of a keyword argument given under its old
name; each with one :class:`DeprecationWarning` line naming both (PEP 562).
"""

from __future__ import annotations

import sys
import warnings
from typing import Callable, Mapping

__all__ = ["old_names", "renamed_keyword"]


def old_names(module: str, renamed: Mapping[str, str]) -> Callable[[str], object]:
    """The module ``__getattr__`` of ``module`` for its ``renamed`` names (old -> new)."""

    def __getattr__(name: str):
        new = renamed.get(name)
        if new is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        warnings.warn(f"{module}.{name} is deprecated: use {module}.{new} (the same object)",
                      DeprecationWarning, stacklevel=2)
        return getattr(sys.modules[module], new)

    return __getattr__


_MISSING = object()


def renamed_keyword(function: str, old: str, old_value, new: str, new_value, default=_MISSING):
    """The value of keyword ``new`` of ``function``, given as ``new_value`` or under its old
    name ``old`` (``old_value``; a warning); None means not given, then ``default`` (a
    TypeError, as Python's, if there is none or if both names are given)."""
    if old_value is None:
        if new_value is None:
            if default is _MISSING:
                raise TypeError(f"{function}() missing required keyword argument: {new!r}")
            return default
        return new_value
    if new_value is not None:
        raise TypeError(f"{function}() got {new!r} and its deprecated name {old!r}; expected one")
    warnings.warn(f"{function}(): keyword {old} is deprecated: use {new} (the same setting)",
                  DeprecationWarning, stacklevel=3)
    return old_value
