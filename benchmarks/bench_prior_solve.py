"""Throughput of ``mcsweep-prior solve`` (library path) on synthetic few-transit sources.

n sources with k FoV transits each (random times in 2015, scan angles, Gaia's position
from the ephemeris table, AL and AC residuals). Measured in the same run:

* baseline: the astrometry stage alone on ready padded arrays (design matrix, normal
  equations, one prior solution), the least any solve must do;
* solve: :func:`mcsweep.prior.observations.solve_observations` (grouping and padding,
  prior, two-parameter and no-prior solutions, ellipses, output table).

Best of ``--repeat``; the machine may be shared, so compare the ratio.

    python benchmarks/bench_prior_solve.py --sources 100000 --transits 4
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mcsweep.astrometry.design import design_matrix, reference_epoch, years_since
from mcsweep.astrometry.solve import normal_equations, solve_with_prior
from mcsweep.prior import Prior
from mcsweep.prior.observations import TransitTable, solve_observations
from mcsweep.scanning.ephemeris import gaia_position_au


def synthetic(n: int, k: int, seed: int = 0) -> TransitTable:
    rng = np.random.default_rng(seed)
    sid = np.repeat(np.arange(n, dtype=np.int64), k)
    tcb = 2457023.5 + np.sort(rng.uniform(0, 365, (n, k)), axis=1).ravel()
    obs = TransitTable(source_id=sid, tcb_jd=tcb, scan_angle_deg=rng.uniform(0, 360, n * k),
                       al_residual_mas=rng.normal(0, 0.2, n * k), al_sigma_mas=np.full(n * k, 0.2),
                       ac_residual_mas=rng.normal(0, 1.0, n * k), ac_sigma_mas=np.full(n * k, 1.0))
    obs["source_ids"] = np.arange(n, dtype=np.int64)
    obs["source_ra"] = rng.uniform(0, 360, n)
    obs["source_dec"] = np.degrees(np.arcsin(rng.uniform(-1, 1, n)))
    obs["source_phot_g_mean_mag"] = rng.uniform(12, 20, n)
    obs["has_ac"], obs["has_observer"] = True, False
    return obs


def best(fn, repeat):
    t = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        t = min(t, time.perf_counter() - t0)
    return t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", type=int, default=100_000)
    ap.add_argument("--transits", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    n, k = a.sources, a.transits
    obs = synthetic(n, k)
    prior = Prior.paper()
    tcb = obs["tcb_jd"].reshape(n, k)
    ep = reference_epoch(tcb)
    psi = obs["scan_angle_deg"].reshape(n, k)
    xyz = gaia_position_au(tcb)
    h = np.concatenate([(obs["al_residual_mas"] / 0.2).reshape(n, k), obs["ac_residual_mas"].reshape(n, k)], axis=1)

    def baseline():
        A = design_matrix(obs["source_ra"], obs["source_dec"], years_since(tcb, ep), psi, xyz,
                          sigma_al_mas=0.2, sigma_ac_mas=1.0)
        N0, b0 = normal_equations(A, h)
        solve_with_prior(N0, b0, 1.0, 10.0)

    t_base = best(baseline, a.repeat)
    t_solve = best(lambda: solve_observations(obs, prior), a.repeat)
    print("machine shared with other jobs: compare ratios, not absolute rates")
    print(f"sources x transits           {n} x {k}")
    print(f"baseline astrometry core     {t_base:.3f} s  ({n / t_base:.3g} sources/s)")
    print(f"solve_observations           {t_solve:.3f} s  ({n / t_solve:.3g} sources/s)")
    print(f"ratio solve / baseline       {t_solve / t_base:.2f}")


if __name__ == "__main__":
    main()
