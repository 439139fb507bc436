"""Whole-sky secondary solution for stars with 95 % diluted histories (paper Sect. 4.1, Table 2).

The attitude is known from an earlier solution, so each star is solved on its own
("secondary" solution: stars only). Procedure, following Sect. 4.1:

1. *Stars.* For each magnitude class G0 (11, 15, 19) the ``class_size`` (5e5) brightest
   stars fainter than G0 over the whole sky (:mod:`mcsweep.experiments.global_solution.classes`).
2. *Transits.* Every star's FoV transits of the configured scanning law (default: the
   NSL as flown) over ``mission_years`` from ``mission_start`` (2014-07-25 10:30 TCB, the
   start of routine operations; the commanded scan law begins 2014-07-25 10:31:26 TCB;
   Gaia Collaboration, Prusti et al. 2016, A&A 595, A1. The first 28 days were in
   fact scanned with the ecliptic-pole scanning law, which is not modelled: the NSL is
   used throughout). No attitude errors.
3. *Dilution.* Each FoV transit is removed with probability ``dilution`` (0.95), drawn
   with the counter-based hash of :func:`mcsweep.scanning.timeline.keep_after_dilution`
   from the star's index in its class (:func:`~mcsweep.experiments.global_solution.classes.diluted`).
4. *Solutions.* Stars with at least one retained transit: AL (and AC, per the noise
   config) measurements of :class:`~mcsweep.astrometry.noise.NoiseModel`, the astrometric
   parameters referred to the epoch of ``reference_epoch``
   (:func:`~mcsweep.experiments.global_solution.epoch.resolve_reference_epoch`; default ``dataset_mean``,
   the mid-point of the mission, one epoch for every star as in a global solution,
   Sect. 2.1; ``star_mean`` is the mean epoch of each star's retained transits),
   ``x_true = (0, 0, parallax, pmra, pmdec)`` (position zero at that epoch), one noise
   realisation shared by every solution: position only (the "none" row), priors of
   0.01 mas, sigma_F90 (Eqs. 14-17, or our own fitted coefficients), 10 sigma_F90 and
   1000 mas with R = sigma_mu / sigma_plx (Eq. 18), and five parameters without prior
   (``solve_no_prior``: ill-conditioned or singular stars count as unsolved).
5. *Table 2.* Per subset (<= 4, > 4 retained transits), prior and class: the fraction
   of stars inside their P confidence ellipse and the 90th percentile of the actual
   position errors (:mod:`mcsweep.experiments.secondary.table`).

Reproducibility: the stars of a class come from ``SeedSequence(seed, spawn_key=(41, 0,
class key))``, its dilution key from ``(41, 1, class key)``, and the measurement noise
of each fixed block of :data:`SECONDARY_NOISE_BLOCK_STARS` consecutive stars from ``(41, 2, class key,
block index)`` (class key = round(100 G0); :mod:`mcsweep.experiments.global_solution.settings`).
Chunks of ``chunk_stars`` (rounded up to a whole number of blocks) only group blocks, so
results are identical for any chunk size, number of workers, backend or completion
order. Each finished chunk is written atomically (:mod:`mcsweep.experiments.global_solution.run`),
so a killed run resumes; the tables are written, atomically, only when every chunk is
done.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ...astrometry.confidence import inside as inside_ellipse
from ...astrometry.confidence import mahalanobis_sq
from ...astrometry.design import design_matrix, years_since
from ...astrometry.measurements import simulate
from ...astrometry.noise import G_MAX
from ...astrometry.solve import normal_equations, solve_no_prior, solve_position_only, solve_with_prior
from ...errors import UserInputError
from ...scanning.ephemeris import gaia_position_au
from ..global_solution.classes import STAR_COLUMNS, class_key, diluted, star_transits
from ..global_solution.priors import prior_sigma_mas
from ..global_solution.settings import GlobalSettings, global_fields, spawn
from ..global_solution.table import g_label
from .table import PRIORS, SOLUTION_COLUMNS

__all__ = [
    "SECONDARY_NOISE_BLOCK_STARS",
    "TAG",
    "SecondarySettings",
    "build_settings",
    "stream_seed",
    "solve_chunk",
    "class_summary",
]

#: Stars per noise block of the secondary experiment (Sect. 4.1): the unit of randomness
#: and of the per-star result store's chunks, so chunking never changes results.
#: Why this size: a block's design arrays are padded to its most-observed star (stars x
#: most transits), so small blocks keep them small and waste little on padding, while
#: 1024 stars amortise the per-block seeding and NumPy call overhead. The value is part of
#: the results: it defines the noise streams (one per block) and the chunk boundaries
#: (chunks hold whole blocks), so a resumed run's finished chunks stay valid only with it;
#: it is fixed.
SECONDARY_NOISE_BLOCK_STARS = 1024
TAG = 41  # Sect. 4.1: first element of every spawn key of this experiment
#: Stream numbers of the spawn keys (dilution, noise; the population's is POPULATION_STREAM = 0).
DILUTION_STREAM, NOISE_STREAM = 1, 2


@dataclasses.dataclass(frozen=True, kw_only=True)
class SecondarySettings(GlobalSettings):
    """Everything a chunk needs besides its stars (picklable, shared by all chunks)."""

    #: Probability that a FoV transit is removed (Sect. 4.1: 95 %).
    dilution: float


def stream_seed(seed: int, stream: int, *key: int) -> np.random.SeedSequence:
    return spawn(seed, TAG, stream, *key)


def build_settings(config) -> SecondarySettings:
    """Settings from a checked :class:`~mcsweep.command.schema.Config`; user errors raised here."""
    sec = config.experiment.secondary
    fields = global_fields(config, "secondary")
    keys = [class_key(g) for g in sec.g_classes]
    if len(set(keys)) != len(keys):
        raise UserInputError(f"experiment.secondary.g_classes={list(sec.g_classes)} is not accepted; "
                             "expected distinct magnitudes (0.01 mag apart or more)")
    if max(sec.g_classes) >= G_MAX:
        raise UserInputError(f"experiment.secondary.g_classes={list(sec.g_classes)} is not accepted; "
                             f"expected magnitudes below {G_MAX:g} (the noise model's limit)")
    return SecondarySettings(**fields, dilution=float(sec.dilution))


# --------------------------------------------------------------------------- solutions
def block_normals(st: dict, sel: np.ndarray, rows: dict, k: int, settings: SecondarySettings, rng):
    """Normal equations of the stars ``sel`` (all with >= 1 transit) of one noise block."""
    nb = sel.size
    shape = (nb, k)
    t, psi = np.full(shape, np.nan), np.full(shape, np.nan)
    obs = np.full(shape + (3,), np.nan)
    mask = np.zeros(shape, dtype=bool)
    r, c = rows["star"], rows["col"]
    t[r, c], psi[r, c], obs[r, c], mask[r, c] = rows["t"], rows["psi"], rows["obs"], True
    t_yr = years_since(t, settings.epoch_tcb_jd(t, mask))
    s_al, s_ac = settings.noise.design_sigmas(st["phot_g_mean_mag"][sel])
    A = design_matrix(st["ra"][sel], st["dec"][sel], t_yr, psi, obs, sigma_al_mas=s_al,
                      sigma_ac_mas=s_ac, mask=mask)
    x_true = np.column_stack([np.zeros(nb), np.zeros(nb), st["parallax"][sel], st["pmra"][sel],
                              st["pmdec"][sel]])
    h = simulate(A, x_true, rng, mask=mask)
    return normal_equations(A, h)


def _solutions(N0, b0, sigma_f90_mas, ratio_R):
    """The rows of Table 2 (position only, then each prior row), then five parameters without prior."""
    yield "none", solve_position_only(N0, b0)
    for label in PRIORS[1:]:
        yield label, solve_with_prior(N0, b0, prior_sigma_mas(label, sigma_f90_mas), ratio_R)
    yield "5p", solve_no_prior(N0, b0)


def solve_chunk(settings: SecondarySettings, g_class: float, first: int, stars: dict) -> pd.DataFrame:
    """Per-star results of the stars ``first, first + 1, ...`` of a class (module notes, steps 2-4).

    Parameters
    ----------
    settings : SecondarySettings
    g_class : float
        The class's G0 (its identity in the seeds).
    first : int
        Index in the class of the first star; a multiple of :data:`SECONDARY_NOISE_BLOCK_STARS`.
    stars : mapping of str -> ndarray
        ``ra, dec, l, b`` [deg], ``parallax`` [mas], ``pmra, pmdec`` [mas/yr],
        ``phot_g_mean_mag`` of the chunk's stars.

    Returns
    -------
    pandas.DataFrame
        One row per star: ``star`` (index in the class), ``n_transits`` (before dilution),
        ``n_fov`` (retained), ``sigma_f90_mas``, and per solution (stems of
        :data:`~mcsweep.experiments.secondary.table.SOLUTION_COLUMNS`) ``inside_<stem>``
        (1/0, -1 = not solved or no transit) and ``err_<stem>_mas``.
    """
    if first % SECONDARY_NOISE_BLOCK_STARS:
        raise ValueError(f"first={first} must be a multiple of SECONDARY_NOISE_BLOCK_STARS={SECONDARY_NOISE_BLOCK_STARS}")
    st = {c: np.asarray(stars[c], dtype=float) for c in STAR_COLUMNS}
    n = st["ra"].size
    ckey = class_key(g_class)
    tr = star_transits(st["ra"], st["dec"], settings.start_jd, settings.end_jd, settings.law, first=first,
                       with_fov=True)
    n_transits = np.bincount(tr["star"] - first, minlength=n)
    keep = diluted(stream_seed(settings.seed, DILUTION_STREAM, ckey), tr, settings.dilution)
    src, t = tr["star"][keep].astype(np.int64) - first, tr["t"][keep]
    psi = tr["psi"][keep].astype(float)
    obs = gaia_position_au(t)  # compact transits carry no observer: the same table, kept rows only
    del tr
    n_fov = np.bincount(src, minlength=n)
    row0 = np.concatenate([[0], np.cumsum(n_fov)])  # rows sorted by (star, time)

    normals, solved = [], []
    for lo in range(0, n, SECONDARY_NOISE_BLOCK_STARS):
        hi = min(lo + SECONDARY_NOISE_BLOCK_STARS, n)
        sel = lo + np.flatnonzero(n_fov[lo:hi] > 0)
        if sel.size == 0:
            continue
        rs = slice(row0[lo], row0[hi])
        star = src[rs]
        compact = np.cumsum(n_fov[lo:hi] > 0) - 1
        rows = {"star": compact[star - lo], "col": np.arange(row0[lo], row0[hi]) - row0[star],
                "t": t[rs], "psi": psi[rs], "obs": obs[rs]}
        rng = np.random.default_rng(stream_seed(settings.seed, NOISE_STREAM, ckey, (first + lo) // SECONDARY_NOISE_BLOCK_STARS))
        normals.append(block_normals(st, sel, rows, int(n_fov[sel].max()), settings, rng))
        solved.append(sel)

    sig = settings.sigma_f90_mas(st["l"], st["b"], st["phot_g_mean_mag"])
    out = {"star": (first + np.arange(n)).astype(np.int32), "n_transits": n_transits.astype(np.int16),
           "n_fov": n_fov.astype(np.int16), "sigma_f90_mas": sig.astype(np.float32)}
    sel = np.concatenate(solved) if solved else np.empty(0, dtype=np.int64)
    N0 = np.concatenate([a for a, _ in normals]) if normals else np.empty((0, 5, 5))
    b0 = np.concatenate([b for _, b in normals]) if normals else np.empty((0, 5))
    for name, sol in _solutions(N0, b0, sig[sel], settings.ratio_R):
        stem = SOLUTION_COLUMNS[name]
        dpos = sol.position  # the true position offset is zero
        # No confidence region (NaN rule of astrometry.confidence.inside_counts): flag -1.
        ok = sol.ok & np.isfinite(mahalanobis_sq(dpos, sol.position_cov))
        inside = np.full(n, -1, dtype=np.int8)
        inside[sel[ok]] = inside_ellipse(dpos[ok], sol.position_cov[ok], settings.confidence)
        err = np.full(n, np.nan, dtype=np.float32)
        err[sel[ok]] = np.hypot(dpos[ok, 0], dpos[ok, 1])
        out[f"inside_{stem}"], out[f"err_{stem}_mas"] = inside, err
    return pd.DataFrame(out)


def class_summary(g_class: float, stars: pd.DataFrame, results: pd.DataFrame) -> dict:
    """One row of ``secondary_summary.csv``: counts, transit statistics, unsolved stars."""
    n_fov = results["n_fov"].to_numpy()
    seen = n_fov > 0
    row = {"g_class": g_label(g_class), "n_stars": len(results),
           "g_faintest": float(stars["phot_g_mean_mag"].max()) if len(stars) else float("nan"),
           "g_upper": float(stars.attrs.get("g_upper", float("nan"))),
           "mean_transits_undiluted": float(results["n_transits"].mean()),
           "mean_fov_retained": float(n_fov.mean()),
           "mean_fov_retained_observed": float(n_fov[seen].mean()) if seen.any() else float("nan"),
           "fraction_retained": float(n_fov.sum() / max(1, results["n_transits"].sum())),
           "n_no_transit": int((~seen).sum()), "n_le4": int((seen & (n_fov <= 4)).sum()),
           "n_gt4": int((n_fov > 4).sum()),
           "median_sigma_f90_mas": float(np.median(results["sigma_f90_mas"].to_numpy()[seen]))
           if seen.any() else float("nan")}
    for name, stem in SOLUTION_COLUMNS.items():
        row[f"n_unsolved_{stem}"] = int((results[f"inside_{stem}"].to_numpy()[seen] < 0).sum())
    return row
