"""Where the primary solution's PCG iterations go (Sect. 4.2; docs/notes/table3/preconditioner.md, "Where the iterations go").

Builds the primary experiment's own problem through the CLI (the run stops once its
measurements are prepared), then, for the sigma_F90 prior:

1. solves it to convergence (iterations, as the experiment would);
2. repeats with ``--stop`` iterations and measures how the remaining attitude error is
   distributed over the spline coefficients (share of the squared error in the top 1 % and
   10 %), where those coefficients lie in their segments, and the eigenvalues of the data's
   3 x 3 attitude information at the worst one against typical ones;
3. with ``--windows``, solves again with wider clusters of the banded Schur block
   (:data:`mcsweep.solver.blocks.SCHUR_WINDOW`).

Run: ``python benchmarks/primary_slow_modes.py [--stars 10000] [--classes 19,19.2,19.4]
[--knot-transits 25] [--knot-rule counts] [--stop 100] [--windows 4,8]`` (3 x 10000 faint
stars: ~3 min). The diagnosis in docs/notes/table3/preconditioner.md used knots by equal counts (``counts``, the
default here; the experiment's default is ``uniform`` since 2026-11-27).
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402


class _Prepared(Exception):
    """Raised by the hooked ``prepare`` to stop the CLI run once the data exist."""


def experiment_problem(stars: int, classes: str, knot_transits: float, knot_rule: str = "counts"):
    """(settings, prepared data) of ``mcsweep experiment=primary`` with these sizes."""
    import mcsweep.experiments.primary.runner as runner
    from mcsweep.cli import main

    got = {}
    original = runner.prepare

    def hook(settings, table, transits, **kw):
        got["out"] = (settings, original(settings, table, transits, **kw))
        raise _Prepared

    runner.prepare = hook
    argv = sys.argv
    with tempfile.TemporaryDirectory() as tmp:
        sys.argv = ["mcsweep", "experiment=primary", f"experiment.primary.class_size={stars}",
                    f"experiment.primary.knot_transits={knot_transits}", f"experiment.primary.knot_rule={knot_rule}",
                    "experiment.primary.priors=[F90]",
                    f"experiment.primary.g_classes=[{classes}]", f"hydra.run.dir={tmp}/run"]
        try:
            main()
        except _Prepared:
            pass
        finally:
            sys.argv, runner.prepare = argv, original
    return got["out"]


def attitude_information(data, coef: int) -> np.ndarray:
    """Eigenvalues of the data's 3 x 3 information on one spline coefficient [mas^-2]."""
    from mcsweep.solver.blocks import att_rows

    N = np.zeros((3, 3))
    for b in data.blocks:
        sel = np.flatnonzero((b.j0 <= coef) & (b.j0 + 3 >= coef))
        if sel.size:
            G = att_rows(b, sel) * b.bval[coef - b.j0[sel], sel]
            N += G @ G.T
    return np.linalg.eigvalsh(N)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stars", type=int, default=10000)
    ap.add_argument("--classes", default="19.0,19.2,19.4")
    ap.add_argument("--knot-transits", type=float, default=25.0)
    ap.add_argument("--knot-rule", default="counts", choices=["counts", "uniform"])
    ap.add_argument("--stop", type=int, default=100)
    ap.add_argument("--windows", default="")
    args = ap.parse_args()

    from mcsweep.astrometry.solve import prior_diagonal
    from mcsweep.experiments.global_solution.priors import prior_sigma_mas
    from mcsweep.solver import blocks as B
    from mcsweep.solver import solve_global

    settings, data = experiment_problem(args.stars, args.classes, args.knot_transits, args.knot_rule)
    st, s = data.stars, data.solved
    sig = prior_sigma_mas("F90", settings.sigma_f90_mas(st["l"].to_numpy()[s], st["b"].to_numpy()[s],
                                                        st["phot_g_mean_mag"].to_numpy()[s]))
    problem = data.problem(prior_diagonal(sig, settings.ratio_R))
    kw = dict(rtol=settings.rtol, update_tol_uas=settings.update_tol_uas, max_iter=5000)
    ref = solve_global(problem, data.h, **kw)
    print(f"{problem.n_stars} stars, {problem.n_measurements} measurements, {problem.n_coef} coefficients "
          f"({data.spline.n_segments} segments): {len(ref.history)} iterations, converged {ref.converged}")
    tight = solve_global(problem, data.h, rtol=1e-10, update_tol_uas=1e-4, max_iter=5000)
    part = solve_global(problem, data.h, rtol=0.0, update_tol_uas=0.0, max_iter=args.stop)
    mag = np.linalg.norm(part.attitude - tight.attitude, axis=1)
    order = np.argsort(mag)[::-1]
    share = np.cumsum(mag[order] ** 2) / np.sum(mag ** 2)
    print(f"after {args.stop} iterations: attitude error RMS {1e3 * np.sqrt(np.mean(mag ** 2)):.1f} uas; "
          f"share of the squared error in the top 1 % of coefficients {share[len(share) // 100]:.2f}, "
          f"top 10 % {share[len(share) // 10]:.2f}")
    first = np.r_[data.spline.segment_first, data.spline.n_coef]
    seg = np.searchsorted(first, order[:10], side="right") - 1
    for c, k in zip(order[:5], seg[:5]):
        print(f"  coefficient {c}: position {c - first[k]} of {first[k + 1] - first[k]} in its segment, "
              f"error {1e3 * mag[c]:.0f} uas, information eigenvalues {np.round(attitude_information(data, c), 4)}")
    for c in np.linspace(0, problem.n_coef - 1, 4).astype(int):
        print(f"  typical coefficient {c}: information eigenvalues {np.round(attitude_information(data, c), 4)}")
    original = B.schur_absorption
    for w in [int(x) for x in args.windows.split(",") if x]:
        B.schur_absorption = functools.partial(original, window=w)
        try:
            sol = solve_global(problem, data.h, **kw)
        finally:
            B.schur_absorption = original
        print(f"Schur window {w}: {len(sol.history)} iterations (window {B.SCHUR_WINDOW}: {len(ref.history)})")


if __name__ == "__main__":
    main()
