"""Tables a user gives mcsweep: formats, one reader, exact integer identifiers.

Below every stage (it imports only :mod:`mcsweep.errors`): the population reads
catalogues with it, the prior the tables to annotate and its run files, the command
``mcsweep-prior solve`` observations and Gaia epoch astrometry.
"""

from .formats import ASTROPY_FORMAT, FORMATS, detect_format
from .ids import integer_ids
from .read import Ragged, TableChunk, as_ragged, iter_tables, read_table

__all__ = ["FORMATS", "ASTROPY_FORMAT", "detect_format", "integer_ids", "Ragged", "TableChunk", "as_ragged",
           "iter_tables", "read_table"]
