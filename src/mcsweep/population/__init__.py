"""population stage (see docs/architecture.md)."""
