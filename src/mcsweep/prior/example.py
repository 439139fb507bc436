"""Example input for ``mcsweep-prior solve``, written by the project's own simulator.

Sources at random directions and G, their FoV transits in a short stretch of the flown
scanning law (:func:`mcsweep.scanning.find_transits`, so only a few transits each), AL
and AC uncertainties from :class:`mcsweep.astrometry.noise.NoiseModel`, and residuals
``A x_true + noise`` (:func:`mcsweep.astrometry.measurements.simulate`) for true
parameters drawn around the paper's prior: parallax ``|N(0, sigma_F90)|`` and proper
motion ``N(0, R sigma_F90)``, position offset 0 at each source's mean epoch. The truth
is illustrative (not a galaxy model); the example shows the file format and lets a test
check that the command reproduces the library's solutions.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..astrometry.design import design_matrix, reference_epoch, years_since
from ..astrometry.measurements import simulate
from ..astrometry.noise import NoiseModel
from ..scanning import find_transits
from ..galactic import galactic_from_icrs
from .model import Prior

__all__ = ["simulate_example"]


def simulate_example(n_sources: int = 20, *, seed: int = 2015, start: str = "2015-03-01T00:00:00",
                     days: float = 60.0, g_range=(12.0, 19.0)):
    """``(observations, sources)`` DataFrames in the format of :mod:`mcsweep.prior.observations`.

    ``sources`` also holds the true parameters (``true_*`` columns) and the padded
    arrays are reproducible from ``seed``. Sources without any transit in the interval
    are dropped.
    """
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(15,)))
    ra = rng.uniform(0, 360, n_sources)
    dec = np.degrees(np.arcsin(rng.uniform(-1, 1, n_sources)))
    g = rng.uniform(*g_range, n_sources)
    from astropy.time import Time

    from astropy import units as u

    t0 = Time(start, scale="tcb")
    tr = find_transits(ra, dec, t0, t0 + days * u.day)
    idx = tr["source_index"].to_numpy()
    keep = np.unique(idx)
    starts = np.searchsorted(idx, keep)
    counts = np.diff(np.r_[starts, idx.size])
    row = np.repeat(np.arange(keep.size), counts)
    col = np.arange(idx.size) - starts[row]
    n, k = keep.size, int(counts.max())
    mask = np.zeros((n, k), bool)
    mask[row, col] = True

    def pad(v):
        a = np.zeros((n, k) + v.shape[1:])
        a[row, col] = v
        return a

    tcb = pad(tr["tcb_jd"].to_numpy())
    psi = pad(tr["scan_angle_deg"].to_numpy())
    obs = pad(tr[["obs_x_au", "obs_y_au", "obs_z_au"]].to_numpy())
    gk = g[keep]
    noise = NoiseModel()
    s_al = np.broadcast_to(noise.sigma_al_mas(gk)[:, None], (n, k))
    s_ac = np.broadcast_to(noise.sigma_ac_mas(gk)[:, None], (n, k))
    epoch = reference_epoch(np.where(mask, tcb, np.nan), mask)
    A = design_matrix(ra[keep], dec[keep], years_since(np.where(mask, tcb, epoch[:, None]), epoch), psi, obs,
                      sigma_al_mas=s_al, sigma_ac_mas=s_ac, mask=mask)
    prior = Prior.paper()
    sig = prior.sigma_parallax_mas(*galactic_from_icrs(ra[keep], dec[keep]), gk)
    x_true = np.zeros((n, 5))
    x_true[:, 2] = np.abs(rng.normal(0.0, sig))
    x_true[:, 3:] = rng.normal(0.0, prior.ratio_R * sig[:, None], (n, 2))
    h = simulate(A, x_true, rng, mask=mask)
    source_id = 4_000_000_000 + keep.astype(np.int64)
    observations = pd.DataFrame({
        "source_id": source_id[row],
        "tcb_jd": tcb[row, col],
        "scan_angle_deg": psi[row, col],
        "al_residual_mas": h[:, :k][row, col] * s_al[row, col],
        "al_sigma_mas": s_al[row, col],
        "ac_residual_mas": h[:, k:][row, col] * s_ac[row, col],
        "ac_sigma_mas": s_ac[row, col],
        "obs_x_au": obs[row, col, 0], "obs_y_au": obs[row, col, 1], "obs_z_au": obs[row, col, 2],
    })
    sources = pd.DataFrame({"source_id": source_id, "ra": ra[keep], "dec": dec[keep], "phot_g_mean_mag": gk,
                            "true_parallax_mas": x_true[:, 2], "true_pmra_mas_yr": x_true[:, 3],
                            "true_pmdec_mas_yr": x_true[:, 4]})
    return observations, sources
