"""astrometry stage (see docs/architecture.md)."""
