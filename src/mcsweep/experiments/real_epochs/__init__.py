"""Real Gaia DR4 epoch astrometry: random subsets of each source's real transits solved with
and without the prior, against the source's all-transit solution as truth (the paper's
Sect. 4.1 test, Table 2, on real measurements instead of simulated ones).

``conf`` its config section, ``inputs`` the epoch file and sources table, ``subsets`` the
seeded draws of transits and visits, ``solutions`` the truths and the subsets' solutions,
``table`` its tables, ``runner`` the run (chunks of sources through the executor, resume),
``section`` its part of the report.
"""

from __future__ import annotations

from ..spec import ExperimentSpec
from .conf import RealEpochsConf

__all__ = ["EXPERIMENT", "CHUNKS_DIR", "TABLE", "SOURCES_TABLE", "FIGURE", "IGNORES"]

#: Sub-directory of the run directory holding the finished chunks of sources.
CHUNKS_DIR = "real_epochs_chunks"
#: One row per unit x k x prior x class of stars.
TABLE = "real_epochs.csv"
#: One row per source x unit x k x prior.
SOURCES_TABLE = "real_epochs_sources.csv"
#: The report's figure: fraction inside against k per prior.
FIGURE = "real_epochs_fraction.png"
#: Top-level settings it never reads: the stars, their transits and their measurements are
#: the epoch file's; the sweep's grid and the prior's model are not used (the paper's prior,
#: or a sweep's fit read from its run directory).
IGNORES = ("sky", "magnitudes", "prior_grid", "cell", "observations", "noise", "population", "scanning",
           "prior_maps", "prior_model")


def _run(config, raw_cfg, run_dir, prov):
    from .runner import run

    return run(config, raw_cfg, run_dir, prov)


def _report(doc, run_dir, prov):
    from .section import real_epochs_section

    real_epochs_section(doc, run_dir, prov)


def _kept(config, config_hash, run_dir):
    from .runner import kept

    return kept(config, config_hash, run_dir)


EXPERIMENT = ExperimentSpec(
    kind="real_epochs", title="random subsets of real Gaia DR4 epoch astrometry",
    sections={"real_epochs": RealEpochsConf}, run=_run, report=_report, kept=_kept,
    outputs=(CHUNKS_DIR, TABLE, SOURCES_TABLE, FIGURE), report_reads=(TABLE, SOURCES_TABLE), ignores=IGNORES)
