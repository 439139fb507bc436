"""Gaia scanning law: attitude, field-of-view transits and the observer's position."""

from .ephemeris import gaia_position_au, sun_position_au
from .groups import assign_groups, group_summary, select_groups
from .law import ScanningLaw
from .transits import TRANSIT_COLUMNS, find_transits, observer_position_au

__all__ = [
    "ScanningLaw",
    "find_transits",
    "observer_position_au",
    "select_groups",
    "assign_groups",
    "group_summary",
    "TRANSIT_COLUMNS",
    "gaia_position_au",
    "sun_position_au",
]
