"""The registry's description of a global experiment (paper Sect. 4): the whole-sky
experiments all run along :func:`~mcsweep.experiments.global_solution.run.run_global`."""

from __future__ import annotations

from typing import Callable

from ..spec import ExperimentSpec

__all__ = ["global_experiment_spec", "GLOBAL_IGNORES"]

#: What no global experiment reads: the sweep's directions, G bins, prior grid, cell
#: procedure and prior maps, and the pencil-beam cases. ``observations.start`` / ``end`` are
#: read under a release preset (``observations=dr1..dr5`` sets the mission), so they stay in
#: the hash; ``observations.reference_epoch`` too (the reference epoch is a mean epoch of
#: observation, paper Sect. 2.1, or a date). ``prior_model`` shapes the sweep's prior only: a
#: global experiment takes its prior from the paper or from a sweep's run directory.
GLOBAL_IGNORES = ("sky", "magnitudes", "prior_grid", "cell", "observations.cases", "observations.f90_case",
                  "observations.fixed_epoch", "prior_maps", "prior_model")


def global_experiment_spec(*, load: Callable[[], tuple], **fields) -> ExperimentSpec:
    """The spec of a global experiment: ``load()`` imports and returns its
    :class:`~mcsweep.experiments.global_solution.run.GlobalExperiment` and its report
    section, on first use; ``fields`` are the other fields of
    :class:`~mcsweep.experiments.spec.ExperimentSpec`."""

    def run(config, raw_cfg, run_dir, prov):
        from .run import run_global

        return run_global(load()[0], config, raw_cfg, run_dir, prov=prov)

    def report(doc, run_dir, prov):
        load()[1](doc, run_dir, prov)

    def kept(config, config_hash, run_dir):
        from .run import kept_chunks

        return kept_chunks(load()[0], config, config_hash, run_dir)

    return ExperimentSpec(run=run, report=report, kept=kept, **fields)
