"""The sigma_F90 sweep: pencil-beam cells over the sky and G, the optimum prior of each,
and the fit of Eqs. 14-17 (paper Sect. 3); the main job.

``conf`` its config sections, ``cells`` the directions and G bins, ``pencil_beam`` one cell
(Sect. 3.2-3.3), ``fit`` the fit over the sky (Sect. 3.4) and the prior maps, ``runner``
the stages, ``section`` and ``figures`` its report (Figs. 1-4).
"""

from __future__ import annotations

from pathlib import Path

from ...prior.maps import MAPS_FILE
from ...prior.run_record import COEFFICIENTS_FILE
from ..spec import ExperimentSpec
from .conf import ShowcaseConf

__all__ = ["EXPERIMENT", "CELLS_DIR", "SHOWCASE_DIR", "FIT_FILES"]

#: Sub-directory of the run directory holding the finished cells.
CELLS_DIR = "cells"
#: Sub-directory holding the single-direction showcase of Figs. 1-3.
SHOWCASE_DIR = "showcase"
#: The fit's tables in a run directory, by file name: the FitResult field each holds.
FIT_FILES = {"f90_cells.csv": "compared", COEFFICIENTS_FILE: "coefficients", "rms_dex.csv": "rms",
             "eq14_terms.csv": "terms"}


def _run(config, raw_cfg: dict, run_dir: Path, prov) -> Path:
    from .runner import run_sweep

    return run_sweep(config, raw_cfg, run_dir, prov=prov)


def _report(doc, run_dir: Path, prov: dict) -> None:
    from .section import sweep_section

    sweep_section(doc, run_dir, prov)


def _kept(config, config_hash: str, run_dir: Path) -> str:
    from ...runtime.store import ResultStore
    from .cells import enumerate_cells

    cells = {c.cell_id for c in enumerate_cells(config.sky, config.magnitudes, config.prior_model.colour_edges)}
    done = ResultStore(Path(run_dir) / CELLS_DIR, config_hash).finished()
    return f"{sum(c in cells for c in done)} of {len(cells)} cells kept in {run_dir}"


# experiment.secondary stays in the sweep's hash: it did before the registry, and every
# sweep run made before would otherwise no longer resume.
EXPERIMENT = ExperimentSpec(
    kind="f90_sweep", title="Sect. 3: sigma_F90 over the sky, the main job", sections={"showcase": ShowcaseConf},
    run=_run, report=_report, kept=_kept,
    outputs=(CELLS_DIR, SHOWCASE_DIR, "cells.parquet", *FIT_FILES, MAPS_FILE), report_reads=(*FIT_FILES, MAPS_FILE),
    hashed_sections=("secondary",))
