"""The galaxy model against published and real data (see docs/architecture.md).

Each tool runs as ``python -m mcsweep.validation.<tool>``: :mod:`.population_validation`,
:mod:`.hipparcos_population`, :mod:`.thickness_grid`; :mod:`.published_counts` holds the
published facts they compare with. Nothing here builds a run's report, and nothing here
imports :mod:`mcsweep.report`.
"""
