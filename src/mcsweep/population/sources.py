"""Choosing a population source from the configuration.

The ``population`` config group (``conf/population/galaxy_model.yaml`` or
``catalogue.yaml``) is a mapping with ``name`` plus that source's keys;
:func:`make_source` turns it into a :class:`~mcsweep.population.GalaxyModel` or a
:class:`~mcsweep.population.CatalogueSource`. Both implement :class:`PopulationSource`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol, runtime_checkable

from ..errors import UserInputError
from .catalogue import CatalogueSource
from .galaxy import DEFAULT_PARAMS, GalaxyModel

__all__ = ["PopulationSource", "make_source", "CATALOGUE_KEYS", "GALAXY_MODEL_KEYS"]

#: Keys of ``conf/population/catalogue.yaml`` besides ``name``.
CATALOGUE_KEYS = ("path", "format", "columns", "units", "on_missing")
#: Keys of ``conf/population/galaxy_model.yaml`` besides ``name``.
GALAXY_MODEL_KEYS = tuple(DEFAULT_PARAMS)


@runtime_checkable
class PopulationSource(Protocol):
    """What experiments need from a source of 'true' stars (see docs/architecture.md)."""

    def sample_cone(self, l_deg, b_deg, radius_deg, g_min, g_max, rng, max_stars=None): ...

    def expected_count(self, l_deg, b_deg, radius_deg, g_min, g_max): ...

    def sample_sky(self, g_min, g_max, rng, max_stars=None): ...


def _plain(value):
    """OmegaConf containers -> plain dicts/lists (without importing omegaconf eagerly)."""
    try:
        from omegaconf import OmegaConf
    except ImportError:  # pragma: no cover - hydra-core is a dependency
        return value
    if OmegaConf.is_config(value):
        return OmegaConf.to_container(value, resolve=True)
    return value


def _unset(value):
    return value is None or (isinstance(value, (dict, list, tuple)) and len(value) == 0)


def _mapping(value):
    """A plain dict from a mapping, a sequence of (key, value) pairs or None."""
    if _unset(value):
        return {}
    if isinstance(value, Mapping):
        return dict(value)
    try:
        return {k: v for k, v in value}
    except (TypeError, ValueError):
        raise UserInputError(f"population: {value!r} is not accepted; expected a mapping") from None


def make_source(cfg):
    """Build the population source described by a config mapping.

    Parameters
    ----------
    cfg : mapping
        ``name`` ('galaxy_model' or 'catalogue') and that group's keys. For the galaxy
        model, the keys of :data:`GALAXY_MODEL_KEYS` (a nested ``params`` mapping is also
        accepted); for a catalogue, ``path`` and optionally ``format``, ``columns``,
        ``units`` and ``on_missing``. Keys whose value is None are ignored.

    Returns
    -------
    GalaxyModel or CatalogueSource

    Raises
    ------
    mcsweep.errors.UserInputError
        For an unknown name, unknown keys, a missing catalogue path or any error the
        source itself reports.
    """
    cfg = _plain(cfg)
    if not isinstance(cfg, Mapping):
        raise UserInputError(f"population={cfg!r} is not accepted; expected a mapping with 'name'")
    cfg = {k: _plain(v) for k, v in cfg.items()}
    name = cfg.pop("name", None)
    if name == "galaxy_model":
        params = _mapping(cfg.pop("params", None))
        for k in CATALOGUE_KEYS:  # tolerate a schema that carries every key, unset
            if _unset(cfg.get(k)) or cfg.get(k) in ("auto", "error"):
                cfg.pop(k, None)
        params.update({k: v for k, v in cfg.items() if v is not None})
        return GalaxyModel(params)
    if name == "catalogue":
        if not _mapping(cfg.pop("params", None)) == {}:
            raise UserInputError("population.params is not accepted with population=catalogue; "
                                 "expected catalogue keys " + str(list(CATALOGUE_KEYS)))
        cfg = {k: v for k, v in cfg.items() if not _unset(v)}
        for k in ("columns", "units"):
            if k in cfg:
                cfg[k] = _mapping(cfg[k])
        unknown = sorted(k for k in set(cfg) - set(CATALOGUE_KEYS) if cfg[k] is not None)
        if unknown:
            raise UserInputError(f"population: unknown catalogue key(s) {unknown}; "
                                 f"expected some of {list(CATALOGUE_KEYS)}")
        path = cfg.get("path")
        if not path or path == "???":
            raise UserInputError("population.path is missing; expected the path of a catalogue "
                                 "file (population=catalogue population.path=FILE)")
        kwargs = {k: cfg[k] for k in CATALOGUE_KEYS[1:] if cfg.get(k) is not None}
        return CatalogueSource(path, **kwargs)
    raise UserInputError(f"population={name!r} is not accepted; expected 'galaxy_model' or "
                         "'catalogue'")
