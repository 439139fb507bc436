"""Gaia scanning law: attitude, field-of-view transits and the observer's position."""

from ..lazy_exports import attach

# imported on first use (mcsweep.lazy_exports): the config schema needs two of these names,
# not scipy.stats, astropy and pandas
__getattr__, __dir__, __all__ = attach(__name__, {
    "ephemeris": ["gaia_position_au", "sun_position_au", "observer_position_au"],
    "groups": ["VISIT_MAX_GAP_DAYS", "VISIT_MAX_TURN_DEG", "assign_groups", "group_summary", "select_groups"],
    "law": ["ScanningLaw"],
    "transits": ["TRANSIT_COLUMNS", "find_transits"],
})
