"""Python names that were renamed keep working under their old names, with a warning.

A public name is a contract, like a config key (:mod:`mcsweep.command.renamed`): scripts
written before a rename must still run. :func:`old_names` gives a module the
``__getattr__`` that answers an old name with the new name's object and one
:class:`DeprecationWarning` line naming both (PEP 562).
"""

from __future__ import annotations

import sys
import warnings
from typing import Callable, Mapping

__all__ = ["old_names"]


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
