"""The figures of the experiment pages, taken from recorded runs' reports.

Each experiment page shows the key figures of a run at its defaults (the sigma_F90 sweep's
Fig. 3 and Fig. 4 analogues and maps, the colour priors' widths and fractions, Table 3's
convergence, the real sky's fractions inside per band and colour). They are never drawn by
hand: this script copies a run's report figures into ``docs/experiments/figures/`` and writes
beside each a MyST snippet, ``<name>.md``, with the figure, its caption and, under it, the run
that made it: the command (from the run's ``.hydra/overrides.yaml``), the run's date (when
its ``provenance.json`` was written) and its commit. The pages include the snippets, so a
figure and its provenance always travel together.

Run, after the runs (each a ``hydra.run.dir``; any subset)::

    mcsweep hydra.run.dir=runs/sweep
    mcsweep prior_model=colour hydra.run.dir=runs/colour
    mcsweep experiment=primary hydra.run.dir=runs/primary
    mcsweep experiment=real_sky experiment.real_sky.colour_priors=[runs/colour] hydra.run.dir=runs/real_sky
    python docs/scripts/results_figures.py --sweep runs/sweep --colour runs/colour \\
        --primary runs/primary --real-sky runs/real_sky
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import shutil
import sys
from pathlib import Path

OUT = Path(__file__).resolve().parents[1] / "experiments" / "figures"

#: per kind of run: (the figure's path in the run's ``figures/``, caption) of the figures its page shows.
FIGURES = {
    "sweep": [
        ("fig3_cases.png", "Errors, formal uncertainties and the fraction inside the 90 % ellipse against the "
                           "prior, for 1, 2, 2 diluted, 4 and 8 distinct transits in the Table 1 beam "
                           "(the paper's Fig. 3)"),
        ("fig4_magnitude.png", "sigma_F90 against G at b = 0, 30 and 90 deg, this run's fit of Eqs. 14-17 "
                               "against the paper's (the paper's Fig. 4, right)"),
        ("fig4_coefficients.png", "The coefficients s0, s1 and s2 of Eq. 14 per G bin, this run's against the "
                                  "paper's Eqs. 15-17 (the paper's Fig. 4, middle)"),
        ("prior_maps.png", "sigma_F90 over the sky at three G values: this run's fitted prior (left) and "
                           "the paper's Eqs. 14-17 (right), galactic Mollweide"),
    ],
    "colour": [
        ("colour_sigma_f90.png", "sigma_F90 against G per BP-RP bin: median over the directions, bars 16-84 % "
                                 "across directions, black the colour-blind cells; lines: the run's prior per bin "
                                 "and the colour-blind one"),
        ("colour_fraction.png", "Fraction of the model's stars inside the 90 % ellipse per BP-RP bin and G bin at "
                                "the bin's fitted width (colour) and at the colour-blind width (grey), median over "
                                "the directions, bars min-max; shaded 88-92 %"),
    ],
    "primary": [
        ("primary_convergence.png", "Table 3: PCG convergence of each global solution, the relative residual "
                                    "of the normal equations, the largest update and the estimated error per "
                                    "iteration"),
    ],
    "real_sky": [
        ("../real_sky_fraction.png", "Hipparcos stars inside their 90 % ellipse per |b| band and prior, with "
                                     "Clopper-Pearson intervals"),
        ("../real_sky_colour.png", "Hipparcos stars inside their 90 % ellipse per |b| band x BP-RP tercile and "
                                   "prior, G = 6-8, with Clopper-Pearson intervals; shaded 88-92 %"),
    ],
}


def run_record(run: Path) -> dict:
    """The command, date and commit of a run directory."""
    prov_path = run / "provenance.json"
    if not prov_path.is_file():
        sys.exit(f"results_figures: {run} has no provenance.json; expected an mcsweep run directory")
    prov = json.loads(prov_path.read_text())
    overrides = []
    over_file = run / ".hydra" / "overrides.yaml"
    if over_file.is_file():
        for line in over_file.read_text().splitlines():
            item = line.strip().removeprefix("- ").strip()
            if item and not item.startswith(("hydra.", "execution.")):
                overrides.append(item)
    date = dt.datetime.fromtimestamp(prov_path.stat().st_mtime, dt.timezone.utc).date().isoformat()
    commit = str(prov.get("git_commit") or "unknown")
    return {"command": " ".join(["mcsweep", *overrides]), "date": date,
            "commit": commit[:7] + ("-dirty" if commit.endswith("-dirty") else "")}


def snippet(name: str, caption: str, rec: dict) -> str:
    """The MyST figure of ``name`` with its caption and the run that made it; the path is the
    one the experiment pages (``docs/experiments/*.md``, which include it) see."""
    return (f"```{{figure}} figures/{name}\n:width: 100%\n\n{caption}. Made by `{rec['command']}` on {rec['date']} "
            f"at commit {rec['commit']} (`docs/scripts/results_figures.py`).\n```\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for kind in FIGURES:
        ap.add_argument(f"--{kind.replace('_', '-')}", type=Path, help=f"the {kind} run directory")
    args = ap.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    written = 0
    for kind, figures in FIGURES.items():
        run = getattr(args, kind)
        if run is None:
            continue
        rec = run_record(run)
        for name, caption in figures:
            src = (run / "figures" / name).resolve()
            if not src.is_file():
                sys.exit(f"results_figures: {src} is missing; expected the report of a {kind} run")
            shutil.copyfile(src, OUT / src.name)
            (OUT / f"{src.stem}.md").write_text(snippet(src.name, caption, rec))
            written += 1
    print(f"{written} figures with their runs -> {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
