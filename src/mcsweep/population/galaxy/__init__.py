"""Built-in Besancon-like galaxy model (thin disc, thick disc, halo, bulge).

Modules: :mod:`.parameters` (published numbers), :mod:`.density` (density laws),
:mod:`.luminosity` (luminosity functions in M_G), :mod:`.extinction` (dust disc),
:mod:`.extinction_arenou` (Arenou et al. 1992 3-D extinction, ``extinction_model=arenou1992``),
:mod:`.kinematics` (velocities and astrometry), :mod:`.model` (:class:`GalaxyModel`).
"""

from .model import DEFAULT_PARAMS, GalaxyModel

__all__ = ["GalaxyModel", "DEFAULT_PARAMS"]
