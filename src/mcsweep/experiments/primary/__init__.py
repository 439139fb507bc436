"""The one-year primary solution, attitude solved from the same data (paper Sect. 4.2, Table 3).

``conf`` its config section; ``experiment`` the settings, the preparation of the stars'
measurements and the evaluation of a solution; ``cluster`` the same on Dask workers;
``prior_solution`` one solution per prior; ``sky``, ``knots`` and ``results`` the
partitions of the sky, the attitude knots and the per-star results; ``reduction``,
``table`` and ``factor`` Table 3 and the factor search; ``runner`` its stages on the global
path; ``section`` and ``figures`` its part of the report.
"""

from __future__ import annotations

from ..global_solution.spec import GLOBAL_IGNORES, global_experiment_spec
from .conf import PrimaryConf

__all__ = ["EXPERIMENT", "CHUNKS_DIR", "TABLES"]

#: Sub-directory of the run directory holding the per-star results of every prior's solution.
CHUNKS_DIR = "primary_chunks"
#: The result files, the main table first.
TABLES = ("table3.csv", "table3.md", "primary_convergence.csv", "primary_summary.csv", "primary_attitude_error.csv",
          "primary_attitude_segments.csv", "primary_factor.csv", "primary_factor_curves.csv")


def _load():
    from .runner import PRIMARY
    from .section import primary_section

    return PRIMARY, primary_section


EXPERIMENT = global_experiment_spec(
    kind="primary", title="Sect. 4.2: one-year primary solution with the attitude, Table 3",
    sections={"primary": PrimaryConf}, load=_load, outputs=(CHUNKS_DIR, *TABLES),
    report_reads=("table3.csv", "primary_summary.csv", "primary_convergence.csv"), ignores=GLOBAL_IGNORES,
    defaults_from_before={
        "experiment.primary.evaluation_epoch": "reference",
        "experiment.primary.subset_transits": "live",  # Table 3's subsets counted by observed transits
        "experiment.primary.basic_angle_harmonics": 0,  # no basic-angle calibration
        "experiment.primary.solver_start": "zero",  # every solution from a zero attitude
        "experiment.primary.knot_rule": "counts",  # knots at equal counts of transits
    },
    # The knot rule places knots only by knot_transits; 3 h knots (the default) ignore it.
    only_with={"experiment.primary.knot_rule": "experiment.primary.knot_transits"},
    # "primary" names the experiment; the extra stars it may add are not Gaia's primary sources.
    renamed_keys={"experiment.primary.primary_sources": "experiment.primary.extra_sources",
                  "experiment.primary.primary_g_min": "experiment.primary.extra_g_min",
                  # a block is a group of stars; the dead time comes in outages
                  "experiment.primary.dead_time_block_days": "experiment.primary.dead_time_outage_days"})
