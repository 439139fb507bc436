"""Gaia scanning law: attitude, field-of-view transits and the observer's position."""

from .ephemeris import gaia_position_au, sun_position_au

__all__ = ["gaia_position_au", "sun_position_au"]
