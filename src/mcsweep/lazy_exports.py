"""Package attributes imported on first use (the pattern of Scientific Python's SPEC 1).

A package's ``__init__`` that imports every module pulls their dependencies (scipy.stats,
astropy, pandas, matplotlib) into any import of any one of them: the config schema, which
needs two constants and the scanning law, took 1.4 s to import, so a mistyped override
waited 3.7 s for its one line. With :func:`attach` the names stay importable from the
package (``from mcsweep.astrometry import NoiseModel``) and each module loads when a name
from it is first asked for.
"""

from __future__ import annotations

import importlib
from typing import Callable, Mapping, Sequence


def attach(package: str, exports: Mapping[str, Sequence[str]]) -> tuple[Callable, Callable, list[str]]:
    """``(__getattr__, __dir__, __all__)`` for ``package`` exporting, per submodule name,
    the names listed in ``exports``."""
    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str):
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        setattr(importlib.import_module(package), name, value)  # later lookups skip this hook
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(importlib.import_module(package))) | set(where))

    return __getattr__, __dir__, list(where)
