"""population stage: the 'true' stars of a cone (see docs/architecture.md).

Two interchangeable sources answer the same queries (:class:`PopulationSource`):

* :class:`GalaxyModel`, a Besancon-like model of the Galaxy built from published numbers
  (the default; works offline), standing in for GUMS (Robin et al. 2012);
* :class:`CatalogueSource`, a table of real or simulated stars (e.g. a GUMS or Gaia DR3
  extract).

:func:`make_source` builds one from the ``population`` config group.
"""

from .catalogue import CatalogueSource
from .galaxy import GalaxyModel
from .query import COLUMNS, POPULATION_CATEGORIES
from .sources import PopulationSource, make_source

__all__ = ["GalaxyModel", "CatalogueSource", "PopulationSource", "make_source", "COLUMNS",
           "POPULATION_CATEGORIES"]
