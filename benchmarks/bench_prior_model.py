"""Cost of the sweep's prior models: a direction x G cell alone (``direction_g``), with its colour
cells (``colour``) and with the prior's mean and the quasars as well (``colour_mean``).

For a few directions and G bins of the default sweep, runs in this process exactly what the
sweep's workers run per direction x G (``run_cell`` of the colour-blind cell, then of each
colour cell of ``prior_model.colour_edges``), with the default cell settings, and prints the
CPU seconds of each model, their ratio to ``direction_g`` measured in the same run, and the
peak memory of one cell (``tracemalloc``). A whole sweep costs about the ratio times the
default sweep; the machine may be shared, so compare the ratios, not the absolute times.

Run: ``python benchmarks/bench_prior_model.py [--directions 3] [--g 8 14 19]``.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402
import tracemalloc  # noqa: E402

from mcsweep.command.validate import compose_config, to_config  # noqa: E402
from mcsweep.experiments.f90_sweep.cells import Cell, colour_bins, sky_directions  # noqa: E402
from mcsweep.experiments.f90_sweep.pencil_beam import run_cell  # noqa: E402
from mcsweep.experiments.f90_sweep.runner import build_settings, direction_transits  # noqa: E402
from mcsweep.population import GalaxyModel  # noqa: E402

MODELS = ("direction_g", "colour", "colour_mean")


def cells_of(model_config, directions, g_values):
    bins = [(None, None)] + colour_bins(model_config.prior_model.colour_edges)
    return [Cell(d, g - 0.5, g + 0.5, c0, c1) for d in directions for g in g_values for c0, c1 in bins]


def run(model: str, directions, g_values, transits, source) -> tuple[float, float, int]:
    config = to_config(compose_config([f"prior_model={model}"]))
    s = build_settings(config)
    cells = cells_of(config, directions, g_values)
    t0 = time.process_time()
    draws: dict = {}
    for c in cells:
        if not c.has_colour:
            draws = {}  # a new direction x G bin: its colour cells share its batches, as in a sweep's job
        run_cell(c, transits[c.direction.index], source, s, draws=draws)
    seconds = time.process_time() - t0
    tracemalloc.start()
    run_cell(cells[-1], transits[cells[-1].direction.index], source, s)
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return seconds, peak, len(cells)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--directions", type=int, default=3, help="directions of the default sky, spread over it")
    ap.add_argument("--g", type=float, nargs="+", default=[8.0, 14.0, 19.0], help="G bin centres")
    args = ap.parse_args()
    config = to_config(compose_config([]))
    every = sky_directions(config.sky)
    directions = every[:: max(1, len(every) // args.directions)][: args.directions]
    transits = direction_transits(config, directions)
    source = GalaxyModel()
    rows = {m: run(m, directions, args.g, transits, source) for m in MODELS}
    base = rows["direction_g"][0]
    print(f"{len(directions)} directions x G {args.g}; default cell settings")
    print(f"{'prior_model':<12} {'cells':>6} {'CPU s':>8} {'ratio':>6} {'peak MB/cell':>13}")
    for m, (sec, peak, n) in rows.items():
        print(f"{m:<12} {n:>6} {sec:>8.2f} {sec / base:>6.2f} {peak:>13.1f}")


if __name__ == "__main__":
    main()
