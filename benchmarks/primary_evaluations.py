"""One primary solution evaluated three ways (Sect. 4.2, Table 3; docs/notes/table3/candidates_paper_sizes.md, "The
candidates at the paper's sizes").

Two of the candidate explanations of the gap to Table 3 (docs/notes/table3/index.md) change only how a
solution is evaluated, not the solution:
the frame rotator fitted with equal weights (``experiment.primary.frame_fit=equal``,
candidate 4) and positions at each star's own mean epoch
(``experiment.primary.evaluation_epoch=star_mean``, candidate 5). At the paper's sizes a
solution takes up to an hour here, so this runs ``mcsweep experiment=primary`` with the
arguments given and evaluates each prior's solution, as it is made, in the run's own way and
in those two, with the experiment's own evaluation
(:func:`evaluate_solution` below: the experiment's block functions composed in this process); each prior's three
Table 3s go to ``evaluations_<prior>.csv`` in the run directory (columns of ``table3.csv``
after ``evaluation``). The run's own evaluation must equal the run's ``table3.csv`` star by
star (checked as it goes); the other two equal the runs with those config values (checked at
3 x 2000 stars: the same counts in every cell). Calibration unknowns
(``basic_angle_harmonics``) border the one solution and are evaluated alike. Local execution
only (forked workers), not ``execution=dask``, whose per-star arrays stay on the workers.

Run: ``python benchmarks/primary_evaluations.py experiment.primary.class_size=500000
experiment.primary.knot_transits=25 'experiment.primary.priors=[F90,10F90]'
hydra.run.dir=DIR`` (any ``mcsweep`` overrides; ``experiment=primary`` is implied).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

#: (name, frame fit with equal weights, positions at each star's mean epoch)
EVALUATIONS = (("run", None, None), ("frame_fit=equal", True, False), ("evaluation_epoch=star_mean", False, True))


def evaluate_solution(K, cov, dx, views, *, equal: bool, tau_yr, confidence: float):
    """``(eps, omega, (inside, err_mas, err_parallax_mas))`` of a solution held in this process:
    the frame rotator fitted to its errors ``dx (n, 5)`` block by block (``views``: the blocks'
    slices, summed in the fixed tree as on a cluster; ``equal``: every star alike) and each
    star's outcome after removing it (:func:`block_outcome`; ``tau_yr``: epochs of evaluation,
    Julian years from the reference epoch, None for the reference epoch)."""
    from mcsweep.experiments.primary.evaluation import block_frame_sums, block_outcome
    from mcsweep.solver.frame import frame_from_sums
    from mcsweep.solver.reduction import pairwise_sum

    eps, omega = frame_from_sums(pairwise_sum(block_frame_sums(K[v], cov[v], dx[v], equal) for v in views)
                                 if views else np.zeros(24))
    parts = [block_outcome(K[v], cov[v], dx[v], eps, omega, None if tau_yr is None else tau_yr[v], confidence)
             for v in views]
    return eps, omega, tuple(np.concatenate([p[i] for p in parts]) if parts else np.zeros(0) for i in range(3))


def evaluations(settings, data, problem, sol, run_result: pd.DataFrame, label: str) -> pd.DataFrame:
    """Table 3 rows of one solution under each of :data:`EVALUATIONS` (``None``: the run's
    setting), the first checked against the run's own per-star result."""
    from mcsweep.experiments.primary.table import table3_rows

    s = data.solved
    views = [slice(b.first, b.first + b.n) for b in data.blocks]
    dx = sol.x - data.x_true
    epoch_offset = data.stars["epoch_offset_yr"].to_numpy()[s]
    keys = run_result["class_key"].to_numpy()
    g_classes = sorted(k / 100.0 for k in np.unique(keys) if k > 0)
    tables = []
    for name, equal, star_mean in EVALUATIONS:
        equal = settings.frame_fit != "precision" if equal is None else equal
        star_mean = settings.evaluation_epoch == "star_mean" if star_mean is None else star_mean
        _, _, (inside, err, _) = evaluate_solution(problem.K, sol.cov, dx, views, equal=equal,
                                                   tau_yr=epoch_offset if star_mean else None,
                                                   confidence=settings.confidence)
        res = run_result.copy()
        res.loc[s, "inside"] = inside
        res.loc[s, "err_mas"] = err.astype(np.float32)
        if name == "run" and not (np.array_equal(res["inside"].to_numpy(), run_result["inside"].to_numpy())
                                  and np.array_equal(res["err_mas"].to_numpy(), run_result["err_mas"].to_numpy(),
                                                 equal_nan=True)):
            raise RuntimeError(f"prior {label}: the run's own evaluation is not reproduced; the script is out of date")
        table = table3_rows({label: res}, g_classes, settings.confidence)
        table.insert(0, "evaluation", name)
        tables.append(table)
    return pd.concat(tables, ignore_index=True)


def main(argv: list[str]) -> None:
    import mcsweep.experiments.primary.local as primary
    import mcsweep.experiments.primary.runner as runner
    from mcsweep.cli import main as cli

    dirs = [a.split("=", 1)[1] for a in argv if a.startswith("hydra.run.dir=")]
    if not dirs or any(a.startswith("execution=dask") for a in argv):
        sys.exit("primary_evaluations: give hydra.run.dir=DIR; execution=dask is not supported")
    run_dir = Path(dirs[0])
    made = {}
    solve_global, solve_prior = primary.solve_global, runner.solve_prior

    def keep(problem, h, **kw):
        made["problem"], made["solution"] = problem, solve_global(problem, h, **kw)
        return made["solution"]

    def evaluated(settings, data, label, *args, **kw):
        out = solve_prior(settings, data, label, *args, **kw)
        table = evaluations(settings, data, made.pop("problem"), made.pop("solution"), out[0], label)
        table.to_csv(run_dir / f"evaluations_{label}.csv", index=False)
        return out

    primary.solve_global, runner.solve_prior = keep, evaluated
    sys.argv = ["mcsweep", *(["experiment=primary"] if "experiment=primary" not in argv else []), *argv]
    try:
        cli()
    finally:
        primary.solve_global, runner.solve_prior = solve_global, solve_prior


if __name__ == "__main__":
    main(sys.argv[1:])
