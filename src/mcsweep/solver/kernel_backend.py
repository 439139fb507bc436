"""The one place through which the solver's tasks reach their compiled kernels.

The blocks' preconditioner passes, the frame sums and the attitude band's scatter
(:mod:`~mcsweep.solver.blocks`, :mod:`~mcsweep.solver.tasks`, :mod:`~mcsweep.solver.problem`,
:mod:`~mcsweep.solver.attitude_update`) call ``active().<kernel>`` at each use, never a
kernel module of their own: a backend with other kernels (a GPU's) is a module with the
functions of :data:`KERNELS` and the same contracts (:mod:`~mcsweep.solver.kernels`' module
notes: results in the measurements' stored order, so bit-identical across chunkings), put in
place with :func:`using`. The default is the CPU's, :mod:`~mcsweep.solver.kernels` (numba).

The choice is this process's: forked workers (:mod:`~mcsweep.solver.resident`) inherit the
kernels active when they fork; a Dask worker (:mod:`~mcsweep.solver.dask_resident`) uses the
default unless its own process chose others.
"""

from __future__ import annotations

import contextlib
from types import ModuleType

from . import kernels as _cpu

__all__ = ["KERNELS", "active", "using"]

#: The kernels a backend provides (those of the CPU module).
KERNELS = tuple(_cpu.__all__)

_active: ModuleType = _cpu


def active() -> ModuleType:
    """The kernels in use in this process (module notes)."""
    return _active


@contextlib.contextmanager
def using(kernels):
    """Use ``kernels`` (any object with the functions of :data:`KERNELS`) while the block runs.

    Raises
    ------
    TypeError
        When ``kernels`` lacks one of :data:`KERNELS`.
    """
    global _active
    missing = [name for name in KERNELS if not callable(getattr(kernels, name, None))]
    if missing:
        raise TypeError(f"kernels {kernels!r} lack {missing}; a backend provides all of {list(KERNELS)}")
    before, _active = _active, kernels
    try:
        yield kernels
    finally:
        _active = before
