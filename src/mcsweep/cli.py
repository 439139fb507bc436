"""The ``mcsweep`` command: a Hydra app running one study per job.

``mcsweep`` with no arguments runs the full default sweep (48 HEALPix directions x
14 G bins x the prior grid) and its report; ``mcsweep experiment=secondary`` runs the
whole-sky secondary solution of Sect. 4.1. Outputs go to Hydra's run directory
(``hydra.run.dir=PATH``); ``mcsweep -m confidence=0.8,0.9,0.95`` runs one job per
value. Bad values end the command with one line on stderr and exit status 2 before
any output is written (:func:`mcsweep.sweep.validate.preflight`).
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from .errors import UserInputError, report_user_error
from .report.build import build_report
from .sweep.provenance import PROVENANCE_FILE, Provenance
from .sweep.runner import run_sweep
from .sweep.logs import quiet_third_party_console
from .sweep.schema import register_configs
from .sweep.secondary_runner import run_secondary
from .sweep.validate import preflight, to_config

__all__ = ["main"]

register_configs()


def _remove_fresh_outputs(run_dir: Path) -> None:
    """Undo what this job and Hydra wrote into a run directory it created (no partial output)."""
    from .experiments.secondary import OUTPUTS as SECONDARY_OUTPUTS
    from .sweep.runner import OUTPUTS

    for name in (".hydra", *OUTPUTS, *SECONDARY_OUTPUTS):
        p = run_dir / name
        if p.is_dir():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)
    for log in run_dir.glob("*.log"):
        log.unlink(missing_ok=True)
    try:
        run_dir.rmdir()  # only if now empty
    except OSError:
        pass


def run_job(cfg: DictConfig, run_dir: Path) -> Path:
    """Run the job described by a composed config in ``run_dir``; returns the report path."""
    config = to_config(cfg)
    raw = OmegaConf.to_container(cfg, resolve=True)
    name = config.experiment.name
    prov = Provenance(run_dir, raw, kind=name)
    prov.check_compatible()
    run = {"f90_sweep": run_sweep, "secondary": run_secondary}[name]
    run(config, raw, run_dir, prov=prov)
    prov.write()
    with prov.stage("report"):
        report = build_report(run_dir)
    prov.write()
    return report


@hydra.main(config_path="conf", config_name="config", version_base="1.3")
def _hydra_entry(cfg: DictConfig) -> None:
    quiet_third_party_console()
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    fresh = not (run_dir / PROVENANCE_FILE).exists()
    try:
        report = run_job(cfg, run_dir)
    except UserInputError as exc:
        if fresh:
            _remove_fresh_outputs(run_dir)
        sys.exit(report_user_error(exc))
    print(f"mcsweep: results in {run_dir} (report: {report})", file=sys.stderr)


def main() -> None:
    try:
        preflight(sys.argv[1:])
    except UserInputError as exc:
        sys.exit(report_user_error(exc))
    _hydra_entry()
