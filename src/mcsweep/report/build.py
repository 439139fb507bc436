"""Build a run directory's report from its result files (reads results, computes none).

Each experiment's section comes from the registry (:mod:`mcsweep.experiments.registry`),
after a check that every result file it reads is there
(:attr:`~mcsweep.experiments.spec.ExperimentSpec.report_reads`): a missing one is reported,
never recomputed. Then the provenance of the run. Writes the figures and ``report.md`` /
``report.html`` only.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pandas as pd

from ..errors import UserInputError
from ..experiments.registry import EXPERIMENTS
from ..runtime.document import Document, plain
from ..runtime.drawing import FigureDrawer

__all__ = ["build_report", "provenance_section"]


def provenance_section(doc: Document, run_dir: Path, prov: dict) -> None:
    doc.heading("Provenance")
    seeds = prov.get("seeds") or {}
    seeds = seeds if isinstance(seeds, dict) else {"seed": seeds}
    doc.para(f"mcsweep {prov.get('mcsweep_version')}, git commit {prov.get('git_commit') or 'unknown'}, "
             f"Python {prov.get('python')}; config hash {prov.get('config_hash')}; seed {plain(seeds.get('seed'))}"
             + ("; the random streams derived from it:" if len(seeds) > 1 else "."))
    streams = []
    for name, how in seeds.items():
        if name == "seed":
            continue
        if isinstance(how, dict):
            streams += [f"{name}, {part}: {plain(v)}" for part, v in how.items()]
        else:
            streams.append(f"{name}: {plain(how)}")
    if streams:
        doc.bullets(streams)
    t = prov.get("timings_s", {})
    if t:
        doc.table(pd.DataFrame({"stage": list(t), "seconds": list(t.values())}), "Per-stage wall time",
                  {"seconds": ".1f"})
    man = prov.get("manifest", [])
    if man:
        doc.para(manifest_summary(man))
    doc.pre(json.dumps(prov.get("config", {}), indent=1, default=str))


def manifest_summary(manifest: list[dict]) -> str:
    """One sentence on the result files; the file-by-file list stays in provenance.json.

    The digest is SHA-256 over the sorted ``path:sha256`` lines, so two runs with the
    same results show the same digest whatever order their files were listed in.
    """
    lines = sorted(f"{m['path']}:{m['sha256']}" for m in manifest)
    digest = hashlib.sha256("\n".join(lines).encode()).hexdigest()
    total = sum(int(m["bytes"]) for m in manifest)
    return (f"Result files of the computation (before this report): {len(manifest)} files, {total / 1e6:.2f} MB in all, manifest digest "
            f"{digest[:16]} (SHA-256 over the sorted path:sha256 lines); each file's size and SHA-256 "
            "are listed under `manifest` in provenance.json.")


def build_report(run_dir) -> Path:
    """Write report.md and report.html in ``run_dir``; returns the Markdown path."""
    run_dir = Path(run_dir)
    pfile = run_dir / "provenance.json"
    if not pfile.exists():
        raise UserInputError(f"{run_dir} is not an mcsweep run directory (no provenance.json); "
                             "expected the directory of a finished run")
    try:
        prov = json.loads(pfile.read_text())
    except (OSError, ValueError) as exc:
        raise UserInputError(f"{pfile} is unreadable ({type(exc).__name__}: {exc}); expected the JSON "
                             "record written by mcsweep") from None
    kind = prov.get("kind", "f90_sweep")
    if kind not in EXPERIMENTS:
        raise UserInputError(f"{pfile}: unknown run kind {kind!r}; expected one of {', '.join(EXPERIMENTS)}")
    experiment = EXPERIMENTS[kind]
    missing = [n for n in experiment.report_reads if not (run_dir / n).is_file()]
    if missing:
        # An unfinished or interrupted run: provenance is written when the inputs are
        # accepted, the results only at the end. Nothing is written here.
        raise UserInputError(
            f"{run_dir} is an unfinished {kind} run: {', '.join(missing)} not written yet; expected a "
            f"finished run (run mcsweep again with hydra.run.dir={run_dir} and the same config to resume)")
    with FigureDrawer(preload=("matplotlib.pyplot",)) as drawer:
        doc = Document(f"mcsweep report: {kind} ({run_dir.name})", drawer=drawer)
        experiment.report(doc, run_dir, prov)
        provenance_section(doc, run_dir, prov)
        md, _ = doc.write(run_dir)
    return md
