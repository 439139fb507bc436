"""Gaia scanning law: attitude, field-of-view transits and the observer's position."""

from .ephemeris import gaia_position_au, sun_position_au
from .groups import VISIT_MAX_GAP_DAYS, VISIT_MAX_TURN_DEG, assign_groups, group_summary, select_groups
from .law import ScanningLaw
from .transits import TRANSIT_COLUMNS, find_transits, observer_position_au

__all__ = [
    "ScanningLaw",
    "find_transits",
    "observer_position_au",
    "select_groups",
    "assign_groups",
    "group_summary",
    "VISIT_MAX_GAP_DAYS",
    "VISIT_MAX_TURN_DEG",
    "TRANSIT_COLUMNS",
    "gaia_position_au",
    "sun_position_au",
]
