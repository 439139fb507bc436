"""sweep stage (see docs/architecture.md)."""
