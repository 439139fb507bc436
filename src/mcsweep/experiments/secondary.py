"""Whole-sky secondary solution for stars with 95 % diluted histories (paper Sect. 4.1, Table 2).

The attitude is known from an earlier solution, so each star is solved on its own
("secondary" solution: stars only). Procedure, following Sect. 4.1:

1. *Stars.* For each magnitude class G0 (11, 15, 19) the ``class_size`` (5e5) brightest
   stars fainter than G0 over the whole sky. From the galaxy model: a faint limit G1 is
   found with ``expected_count(whole sky, G0..G1)`` a little above the class size
   (``class_size + 6 sqrt(class_size)``, so a Poisson draw almost surely holds enough
   stars), the stars of [G0, G1) are drawn, and the ``class_size`` brightest are kept.
   From a catalogue: its brightest stars in [G0, 21) (21 = the noise model's limit).
   Stars keep the order in which the source returned them.
2. *Transits.* Every star's FoV transits of the configured scanning law (default: the
   NSL as flown) over ``mission_years`` from ``mission_start`` (2014-07-25 10:30 TCB, the
   start of routine operations; the commanded scan law begins 2014-07-25 10:31:26 TCB;
   Gaia Collaboration, Prusti et al. 2016, A&A 595, A1. The first 28 days were in
   fact scanned with the ecliptic-pole scanning law, which is not modelled: the NSL is
   used throughout). No attitude errors.
3. *Dilution.* Each FoV transit is removed with probability ``dilution`` (0.95), drawn
   with the counter-based hash of :func:`mcsweep.scanning.timeline.keep_after_dilution`
   from the star's index in its class.
4. *Solutions.* Stars with at least one retained transit: AL (and AC, per the noise
   config) measurements of :class:`~mcsweep.astrometry.noise.NoiseModel`, the astrometric
   parameters referred to the epoch of ``reference_epoch``
   (:func:`~mcsweep.experiments.epoch.resolve_reference_epoch`; default ``dataset_mean``,
   the mid-point of the mission, one epoch for every star as in a global solution,
   Sect. 2.1; ``star_mean`` is the mean epoch of each star's retained transits),
   ``x_true = (0, 0, parallax, pmra, pmdec)`` (position zero at that epoch), one noise
   realisation shared by every solution: position only (the "none" row), priors of
   0.01 mas, sigma_F90 (Eqs. 14-17, or our own fitted coefficients), 10 sigma_F90 and
   1000 mas with R = sigma_mu / sigma_plx (Eq. 18), and five parameters without prior
   (``solve_no_prior``: ill-conditioned or singular stars count as unsolved).
5. *Table 2.* Per subset (<= 4, > 4 retained transits), prior and class: the fraction
   of stars inside their P confidence ellipse and the 90th percentile of the actual
   position errors (:mod:`mcsweep.experiments.secondary_table`).

Reproducibility: the stars of a class come from ``SeedSequence(seed, spawn_key=(41, 0,
class key))``, its dilution key from ``(41, 1, class key)``, and the measurement noise
of each fixed block of :data:`BLOCK_STARS` consecutive stars from ``(41, 2, class key,
block index)`` (class key = round(100 G0)). Chunks of ``chunk_stars`` (rounded up to a
whole number of blocks) only group blocks, so results are identical for any chunk
size, number of workers, backend or completion order. Each finished chunk is written
atomically (:class:`~mcsweep.sweep.store.CellStore`), so a killed run resumes; the
tables are written, atomically, only when every chunk is done.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from astropy.time import Time

from ..astrometry.confidence import chi2_threshold, mahalanobis_sq
from ..astrometry.design import design_matrix, years_since
from ..astrometry.measurements import simulate
from ..astrometry.noise import G_MAX, NoiseModel
from ..astrometry.solve import normal_equations, solve_no_prior, solve_position_only, solve_with_prior
from ..errors import UserInputError
from ..prior import G_FIT_MAX, PAPER_COEFFICIENTS, sigma_f90, sigma_from_coefficients
from ..scanning import ScanningLaw, find_transits
from ..scanning.ephemeris import TABLE_END_JD_TCB, TABLE_START_JD_TCB, gaia_position_au
from ..scanning.timeline import dilution_key, keep_after_dilution
from .epoch import resolve_reference_epoch
from .secondary_table import SOLUTION_COLUMNS, g_label

__all__ = [
    "BLOCK_STARS",
    "CHUNKS_DIR",
    "OUTPUTS",
    "SecondarySettings",
    "build_settings",
    "load_f90_coefficients",
    "faint_limit",
    "select_class_stars",
    "solve_chunk",
    "class_summary",
]

#: Stars per noise block: the unit of randomness, so chunking never changes results.
BLOCK_STARS = 1024
#: Sub-directory of the run directory holding the finished chunks.
CHUNKS_DIR = "secondary_chunks"
#: Everything this experiment and its report write into a run directory (removed again
#: when a fresh run stops on a user error: no partial output).
OUTPUTS = (CHUNKS_DIR, "table2.csv", "table2.md", "no_prior.csv", "secondary_summary.csv", "report.md",
           "report.html", "provenance.json")
#: Prior sigmas of the fixed rows of Table 2 [mas], and the multiple of sigma_F90.
TIGHT_PRIOR_MAS, LOOSE_PRIOR_MAS, F90_FACTOR = 0.01, 1000.0, 10.0
#: Extra stars asked of the galaxy model beyond the class size, in Poisson sigmas.
MARGIN_SIGMAS = 6.0

_TAG = 41  # Sect. 4.1: first element of every spawn key of this experiment
#: Stream numbers of the spawn keys (population, dilution, noise).
POPULATION_STREAM, DILUTION_STREAM, NOISE_STREAM = 0, 1, 2
STAR_COLUMNS = ("ra", "dec", "l", "b", "parallax", "pmra", "pmdec", "phot_g_mean_mag")


@dataclasses.dataclass(frozen=True)
class SecondarySettings:
    """Everything a chunk needs besides its stars (picklable, shared by all chunks)."""

    seed: int
    start_jd: float
    end_jd: float
    law: ScanningLaw
    dilution: float
    noise: NoiseModel
    confidence: float
    ratio_R: float
    #: Coefficients of Eqs. 15-17 as ((name, (c0, c1, ...)), ...); None = the paper's.
    f90_coefficients: tuple | None = None
    #: Reference epoch setting (:func:`~mcsweep.experiments.epoch.resolve_reference_epoch`).
    reference_epoch: str = "dataset_mean"

    def epoch_tcb_jd(self, tcb_jd=None, mask=None) -> np.ndarray:
        """Reference epoch (TCB JD) of each star of ``tcb_jd (n, k)`` (one value without it)."""
        return resolve_reference_epoch(self.reference_epoch, self.start_jd, self.end_jd, tcb_jd, mask)

    def sigma_f90_mas(self, l_deg, b_deg, g) -> np.ndarray:
        """The sigma_F90 prior of each star [mas] (G > 20 uses G = 20, as the paper says)."""
        if self.f90_coefficients is None:
            return sigma_f90(l_deg, b_deg, g)
        return sigma_from_coefficients(l_deg, b_deg, g, dict(self.f90_coefficients), g_max=G_FIT_MAX)


def class_key(g_class: float) -> int:
    """Stable identity of a magnitude class (0.01 mag resolution)."""
    return int(round(100.0 * g_class))


def stream_seed(seed: int, stream: int, *key: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(seed, spawn_key=(_TAG, stream, *key))


def load_f90_coefficients(spec: str) -> tuple | None:
    """None for ``'paper'``; else the fitted coefficients of a sweep's ``coefficients.csv``.

    ``spec`` is the CSV file or the run directory holding it (columns ``term``, ``fitted``;
    terms ``s0_c0`` ... as written by :mod:`mcsweep.report.build`).
    """
    if spec == "paper":
        return None
    path = Path(spec)
    if path.is_dir():
        path = path / "coefficients.csv"
    key = "experiment.secondary.f90_formula"
    if not path.is_file():
        raise UserInputError(f"{key}={spec!r} is not accepted; expected 'paper' or a sweep run's "
                             "coefficients.csv (or its run directory)")
    try:
        table = pd.read_csv(path)
        fitted = dict(zip(table["term"].astype(str), table["fitted"].astype(float)))
        coeffs = tuple((name, tuple(fitted[f"{name}_c{p}"] for p in range(len(PAPER_COEFFICIENTS[name]))))
                       for name in ("s0", "s1", "s2"))
    except (KeyError, ValueError, pd.errors.ParserError, pd.errors.EmptyDataError):
        raise UserInputError(f"{key}={spec!r} is not accepted; expected a CSV with columns term, fitted "
                             "and terms s0_c0..s2_c1 (a sweep run's coefficients.csv)") from None
    if not all(np.isfinite(c).all() for _, c in coeffs):
        raise UserInputError(f"{key}={spec!r} is not accepted; its fitted coefficients are not all finite "
                             "(the sweep could not fit Eqs. 15-17)")
    return coeffs


def build_settings(config) -> SecondarySettings:
    """Settings from a checked :class:`~mcsweep.sweep.schema.Config`; user errors raised here."""
    sec = config.experiment.secondary
    try:
        start = Time(sec.mission_start, scale="tcb")
    except ValueError:
        raise UserInputError(f"experiment.secondary.mission_start={sec.mission_start!r} is not accepted; "
                             "expected an ISO date (TCB) such as '2014-07-25T10:30:00'") from None
    start_jd = float(start.jd)
    end_jd = start_jd + 365.25 * sec.mission_years
    if start_jd < TABLE_START_JD_TCB + 1.0 or end_jd > TABLE_END_JD_TCB - 1.0:
        raise UserInputError(f"experiment.secondary.mission_start={sec.mission_start!r} with mission_years="
                             f"{sec.mission_years:g} is not accepted; expected a mission within 2013-2031 "
                             "(the observer ephemeris)")
    keys = [class_key(g) for g in sec.g_classes]
    if len(set(keys)) != len(keys):
        raise UserInputError(f"experiment.secondary.g_classes={list(sec.g_classes)} is not accepted; "
                             "expected distinct magnitudes (0.01 mag apart or more)")
    if max(sec.g_classes) >= G_MAX:
        raise UserInputError(f"experiment.secondary.g_classes={list(sec.g_classes)} is not accepted; "
                             f"expected magnitudes below {G_MAX:g} (the noise model's limit)")
    return SecondarySettings(
        seed=int(config.seed), start_jd=start_jd, end_jd=end_jd,
        law=ScanningLaw.from_config(dataclasses.asdict(config.scanning)),
        dilution=float(sec.dilution),
        noise=NoiseModel(al_scale=config.noise.al_scale, ac_scale=config.noise.ac_scale,
                         use_ac=config.noise.use_ac),
        confidence=float(config.confidence), ratio_R=float(config.ratio_R),
        f90_coefficients=load_f90_coefficients(sec.f90_formula),
        reference_epoch=str(sec.reference_epoch))


# --------------------------------------------------------------------------- stars
def faint_limit(count, g_min: float, g_limit: float, target: float, *, rtol: float = 0.05,
                max_iter: int = 60) -> float:
    """Smallest convenient G1 with ``target <= count(G1) <= (1 + rtol) target``.

    ``count(g)`` is the (monotone) number of stars in [g_min, g); the search is a
    safeguarded secant in (log(g - g_min), log count), where counts are close to power
    laws. Returns ``g_limit`` if even ``count(g_limit) < target``; if the tolerance is not
    reached (e.g. a catalogue with many equal magnitudes), the bracketing G1 with
    ``count >= target``.
    """
    total = count(g_limit)
    if total < target:
        return g_limit
    lo_x, lo_y = None, -math.inf
    hi_x, hi_y = math.log(g_limit - g_min), math.log(total)
    y_ok, y_aim = math.log(target * (1.0 + rtol)), math.log(target * (1.0 + 0.5 * rtol))
    x = min(math.log(0.01), hi_x - 1.0)
    for _ in range(max_iter):
        if hi_y <= y_ok:
            break
        c = count(g_min + math.exp(x))
        if c >= target:
            hi_x, hi_y = x, math.log(c)
        else:
            lo_x, lo_y = x, (math.log(c) if c > 0 else -math.inf)
        if lo_x is None:
            x = hi_x - 2.0
        elif not math.isfinite(lo_y):
            x = 0.5 * (lo_x + hi_x)
        else:
            x = lo_x + (y_aim - lo_y) * (hi_x - lo_x) / (hi_y - lo_y)
            span = hi_x - lo_x
            if not lo_x + 0.01 * span < x < hi_x - 0.01 * span:
                x = 0.5 * (lo_x + hi_x)
    return g_min + math.exp(hi_x)


def select_class_stars(source, g_min: float, n: int, rng) -> pd.DataFrame:
    """The ``n`` brightest stars with G >= g_min over the whole sky (module notes, step 1).

    ``df.attrs['g_upper']`` is the faint limit of the draw. Fewer than ``n`` stars (a small
    catalogue) are returned with a warning.
    """
    target = n + MARGIN_SIGMAS * math.sqrt(n)
    g_upper = faint_limit(lambda g: source.expected_count(0.0, 90.0, 180.0, g_min, g), g_min, G_MAX, target)
    df = source.sample_sky(g_min, g_upper, rng)
    g = df["phot_g_mean_mag"].to_numpy()
    if len(df) > n:
        keep = np.sort(np.argsort(g, kind="stable")[:n])
        df = df.iloc[keep].reset_index(drop=True)
    elif len(df) < n:
        warnings.warn(f"magnitude class G >= {g_min:g}: only {len(df)} stars available below G = "
                      f"{g_upper:.3f}, fewer than experiment.secondary.class_size={n}", stacklevel=2)
    df.attrs["g_upper"] = g_upper
    return df


# --------------------------------------------------------------------------- solutions
def _block_normals(st: dict, sel: np.ndarray, rows: dict, k: int, settings: SecondarySettings, rng):
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
    yield "none", solve_position_only(N0, b0)
    yield "0.01mas", solve_with_prior(N0, b0, TIGHT_PRIOR_MAS, ratio_R)
    yield "F90", solve_with_prior(N0, b0, sigma_f90_mas, ratio_R)
    yield "10F90", solve_with_prior(N0, b0, F90_FACTOR * sigma_f90_mas, ratio_R)
    yield "1000mas", solve_with_prior(N0, b0, LOOSE_PRIOR_MAS, ratio_R)
    yield "5p", solve_no_prior(N0, b0)


def solve_chunk(settings: SecondarySettings, g_class: float, first: int, stars: dict) -> pd.DataFrame:
    """Per-star results of the stars ``first, first + 1, ...`` of a class (module notes, steps 2-4).

    Parameters
    ----------
    settings : SecondarySettings
    g_class : float
        The class's G0 (its identity in the seeds).
    first : int
        Index in the class of the first star; a multiple of :data:`BLOCK_STARS`.
    stars : mapping of str -> ndarray
        ``ra, dec, l, b`` [deg], ``parallax`` [mas], ``pmra, pmdec`` [mas/yr],
        ``phot_g_mean_mag`` of the chunk's stars.

    Returns
    -------
    pandas.DataFrame
        One row per star: ``star`` (index in the class), ``n_transits`` (before dilution),
        ``n_fov`` (retained), ``sigma_f90_mas``, and per solution (stems of
        :data:`~mcsweep.experiments.secondary_table.SOLUTION_COLUMNS`) ``inside_<stem>``
        (1/0, -1 = not solved or no transit) and ``err_<stem>_mas``.
    """
    if first % BLOCK_STARS:
        raise ValueError(f"first={first} must be a multiple of BLOCK_STARS={BLOCK_STARS}")
    st = {c: np.asarray(stars[c], dtype=float) for c in STAR_COLUMNS}
    n = st["ra"].size
    ckey = class_key(g_class)
    tr = find_transits(st["ra"], st["dec"], settings.start_jd, settings.end_jd, law=settings.law,
                       compact=True)
    src = tr["source_index"].to_numpy().astype(np.int64)
    t = tr["tcb_jd"].to_numpy()
    n_transits = np.bincount(src, minlength=n)
    key = dilution_key(np.random.default_rng(stream_seed(settings.seed, DILUTION_STREAM, ckey)))
    keep = keep_after_dilution(key, first + src, tr["fov"].cat.codes.to_numpy() == 1, t, settings.dilution)
    src, t = src[keep], t[keep]
    psi = tr["scan_angle_deg"].to_numpy()[keep].astype(float)
    obs = gaia_position_au(t)  # compact transits carry no observer: the same table, kept rows only
    del tr
    n_fov = np.bincount(src, minlength=n)
    row0 = np.concatenate([[0], np.cumsum(n_fov)])  # rows sorted by (star, time)

    normals, solved = [], []
    for lo in range(0, n, BLOCK_STARS):
        hi = min(lo + BLOCK_STARS, n)
        sel = lo + np.flatnonzero(n_fov[lo:hi] > 0)
        if sel.size == 0:
            continue
        rs = slice(row0[lo], row0[hi])
        star = src[rs]
        compact = np.cumsum(n_fov[lo:hi] > 0) - 1
        rows = {"star": compact[star - lo], "col": np.arange(row0[lo], row0[hi]) - row0[star],
                "t": t[rs], "psi": psi[rs], "obs": obs[rs]}
        rng = np.random.default_rng(stream_seed(settings.seed, NOISE_STREAM, ckey, (first + lo) // BLOCK_STARS))
        normals.append(_block_normals(st, sel, rows, int(n_fov[sel].max()), settings, rng))
        solved.append(sel)

    sig = settings.sigma_f90_mas(st["l"], st["b"], st["phot_g_mean_mag"])
    out = {"star": (first + np.arange(n)).astype(np.int32), "n_transits": n_transits.astype(np.int16),
           "n_fov": n_fov.astype(np.int16), "sigma_f90_mas": sig.astype(np.float32)}
    k_p = chi2_threshold(settings.confidence, 2)
    sel = np.concatenate(solved) if solved else np.empty(0, dtype=np.int64)
    N0 = np.concatenate([a for a, _ in normals]) if normals else np.empty((0, 5, 5))
    b0 = np.concatenate([b for _, b in normals]) if normals else np.empty((0, 5))
    for name, sol in _solutions(N0, b0, sig[sel], settings.ratio_R):
        stem = SOLUTION_COLUMNS[name]
        dpos = sol.position  # the true position offset is zero
        q = mahalanobis_sq(dpos, sol.position_cov)
        ok = sol.ok & np.isfinite(q)
        inside = np.full(n, -1, dtype=np.int8)
        inside[sel[ok]] = (q[ok] < k_p).astype(np.int8)
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
