"""The whole-sky secondary solution, attitude known (paper Sect. 4.1, Table 2).

``conf`` its config section, ``experiment`` the per-star solutions, ``table`` Table 2,
``runner`` its stages on the global path, ``section`` its part of the report.
"""

from __future__ import annotations

from ..global_solution.spec import GLOBAL_IGNORES, global_experiment_spec
from .conf import SecondaryConf

__all__ = ["EXPERIMENT", "CHUNKS_DIR", "TABLES"]

#: Sub-directory of the run directory holding the finished chunks of stars.
CHUNKS_DIR = "secondary_chunks"
#: The result files, the main table first.
TABLES = ("table2.csv", "table2.md", "no_prior.csv", "secondary_summary.csv")


def _load():
    from .runner import SECONDARY
    from .section import secondary_section

    return SECONDARY, secondary_section


EXPERIMENT = global_experiment_spec(
    kind="secondary", title="Sect. 4.1: whole-sky secondary solution, Table 2", sections={"secondary": SecondaryConf},
    load=_load, outputs=(CHUNKS_DIR, *TABLES), report_reads=("table2.csv", "no_prior.csv", "secondary_summary.csv"),
    ignores=GLOBAL_IGNORES)
