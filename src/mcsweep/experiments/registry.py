"""The experiments mcsweep runs, by kind: the only module that names them all.

Everything that differs between experiments is reached through here: the ``experiment``
config group's sections (:func:`experiment_conf_class`), the run (:func:`get`), the files
it writes and its report reads, its report section, and the keys left out of its config
hash (:func:`ignored_keys`). Adding an experiment is one folder ``experiments/<kind>/``
whose ``__init__`` holds its :class:`~mcsweep.experiments.spec.ExperimentSpec`, one line in
:data:`EXPERIMENTS` (or :func:`register` from outside the package, before the config schema
is built) and one YAML, ``conf/experiment/<kind>.yaml``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from ..errors import UserInputError
from . import f90_sweep, primary, real_epochs, real_sky, secondary
from .spec import ExperimentSpec

__all__ = ["EXPERIMENTS", "register", "get", "ignored_keys", "hash_defaults_from_before", "hash_only_with",
           "renamed_keys", "experiment_conf_class"]

#: Every experiment by kind, in the order they are listed to a user.
EXPERIMENTS: dict[str, ExperimentSpec] = {
    e.kind: e for e in (f90_sweep.EXPERIMENT, secondary.EXPERIMENT, primary.EXPERIMENT, real_sky.EXPERIMENT,
                        real_epochs.EXPERIMENT)}

_conf_class: list[type] = []


def register(spec: ExperimentSpec) -> None:
    """Add an experiment defined outside this package (e.g. a test's). Must come before the
    config schema is built (:mod:`mcsweep.command.schema` imported), which fixes the sections."""
    if _conf_class:
        raise RuntimeError(f"experiment {spec.kind!r} registered after the config schema was built; "
                           "register it before importing mcsweep.command.schema or mcsweep.cli")
    if spec.kind in EXPERIMENTS:
        raise ValueError(f"an experiment {spec.kind!r} is registered already")
    taken = {s for e in EXPERIMENTS.values() for s in e.sections}
    if taken & set(spec.sections):
        raise ValueError(f"config sections {sorted(taken & set(spec.sections))} belong to another experiment")
    EXPERIMENTS[spec.kind] = spec


def _accepted() -> str:
    return ", ".join(f"'{k}' ({e.title})" for k, e in EXPERIMENTS.items())


def get(kind: str) -> ExperimentSpec:
    """The experiment ``kind``; a UserInputError naming the kinds there are."""
    try:
        return EXPERIMENTS[kind]
    except KeyError:
        raise UserInputError(f"experiment={kind!r} is not accepted; expected one of {_accepted()}") from None


def ignored_keys(kind: str) -> tuple[str, ...]:
    """Config keys (dotted; a whole section or one key) experiment ``kind`` never reads: its
    own list and every other experiment's section it does not keep in its hash."""
    spec = EXPERIMENTS.get(kind)
    if spec is None:
        return ()
    keep = set(spec.sections) | set(spec.hashed_sections)
    others = [f"experiment.{s}" for e in EXPERIMENTS.values() for s in e.sections if s not in keep]
    return tuple(spec.ignores) + tuple(others)


def hash_defaults_from_before() -> dict[str, Any]:
    """Every experiment's :attr:`~mcsweep.experiments.spec.ExperimentSpec.defaults_from_before`."""
    return {k: v for e in EXPERIMENTS.values() for k, v in e.defaults_from_before.items()}


def hash_only_with() -> dict[str, str]:
    """Every experiment's :attr:`~mcsweep.experiments.spec.ExperimentSpec.only_with`."""
    return {k: v for e in EXPERIMENTS.values() for k, v in e.only_with.items()}


def renamed_keys() -> dict[str, str]:
    """Every experiment's renamed config keys, old dotted name -> new."""
    return {k: v for e in EXPERIMENTS.values() for k, v in e.renamed_keys.items()}


def experiment_conf_class() -> type:
    """The ``experiment`` config group's dataclass: ``name`` (the kind) and one field per
    section of every registered experiment. Built once; :func:`register` is refused after."""
    if not _conf_class:
        def check_name(self):
            if self.name not in EXPERIMENTS:
                raise UserInputError(f"experiment={self.name!r} is not accepted; expected one of {_accepted()}")

        fields = [("name", str, dataclasses.field(default="f90_sweep"))] + [
            (name, cls, dataclasses.field(default_factory=cls))
            for e in EXPERIMENTS.values() for name, cls in e.sections.items()]
        cls = dataclasses.make_dataclass(
            "ExperimentConf", fields, namespace={"__post_init__": check_name,
                                                 "__doc__": "The experiment to run and every experiment's section."})
        cls.__module__ = __name__
        _conf_class.append(cls)
    return _conf_class[0]


def __getattr__(name: str):
    # ``ExperimentConf`` resolves by name, as pickle needs it to (a config sent to a worker process).
    if name == "ExperimentConf":
        return experiment_conf_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
