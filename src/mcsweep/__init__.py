"""mcsweep: Monte Carlo sweeps of Bayesian Gaia astrometry for under-observed stars.

Reproduces and extends Michalik, Lindegren, Hobbs & Butkevich (2015, A&A 583, A68).
The package reads as the pipeline: ``scanning`` -> ``population`` -> ``astrometry``
(+ ``prior``) -> ``experiments`` -> ``sweep`` -> ``report``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("mcsweep")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0+unknown"

__all__ = ["__version__"]
