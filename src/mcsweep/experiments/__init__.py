"""experiments stage (see docs/architecture.md)."""
