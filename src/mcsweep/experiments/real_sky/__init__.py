"""The real-sky validation: Hipparcos 2 stars as truth (the prior on the real sky).

``conf`` its config section, ``experiment`` the stars, priors and per-star solutions,
``complete`` the fractions carried over to the complete sky, ``runner`` its stages on the
global path, ``section`` its part of the report.
"""

from __future__ import annotations

from ..global_solution.spec import GLOBAL_IGNORES, global_experiment_spec
from .conf import RealSkyConf

__all__ = ["EXPERIMENT", "CHUNKS_DIR", "TABLES", "FIGURE", "COLOUR_FIGURE"]

#: Sub-directory of the run directory holding the finished chunks of stars.
CHUNKS_DIR = "real_sky_chunks"
#: The result files, the main table first.
TABLES = ("real_sky.csv", "real_sky.md", "real_sky_errors.csv", "real_sky_complete.csv")
#: The report's figure of the fractions inside per band of latitude.
FIGURE = "real_sky_fraction.png"
#: The report's figure of the fractions inside per band of latitude x BP-RP bin (drawn
#: only when the table has colour bins).
COLOUR_FIGURE = "real_sky_colour.png"


def _load():
    from .runner import REAL_SKY
    from .section import real_sky_section

    return REAL_SKY, real_sky_section


# The stars are Hipparcos's, so the population config is not read either; the cases are
# (experiment.real_sky.cases names them).
EXPERIMENT = global_experiment_spec(
    kind="real_sky", title="Hipparcos stars as truth", sections={"real_sky": RealSkyConf}, load=_load,
    outputs=(CHUNKS_DIR, *TABLES, FIGURE, COLOUR_FIGURE), report_reads=("real_sky.csv", "real_sky_errors.csv"),
    ignores=tuple(k for k in GLOBAL_IGNORES if k not in ("observations.cases", "observations.fixed_epoch"))
    + ("population",),
    # No colour priors: the validation as before the option existed.
    defaults_from_before={"experiment.real_sky.colour_priors": []})
