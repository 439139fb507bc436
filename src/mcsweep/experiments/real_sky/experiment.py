"""Real-sky validation of the prior: Hipparcos stars as truth.

The F90 prior (paper Sect. 3, Eqs. 14-17, or a sweep's refit) is meant for real stars.
This experiment takes the Hipparcos 2 catalogue (van Leeuwen 2007, CDS I/311;
:mod:`mcsweep.population.hipparcos`, the optional extra ``realsky``) as the truth:

1. *Stars.* Every Hipparcos star with ``g_min <= G < g_max`` (default 6-9; G from Hp and
   the colours, :func:`~mcsweep.population.hipparcos.g_from_hipparcos`); with
   ``max_stars`` an unbiased random subset of them (seeded, stream ``(43, 0, 0)``).
2. *Transits.* Each star's own FoV transits of the configured scanning law at its own
   position over the sweep's observation window (``observations.start`` / ``end``,
   Table 1's interval), grouped into distinct transits (``group``), and per observation
   case the groups of ``observations.cases`` (the sweep's cases: one, two, four, eight
   visits; negative = from the last), chosen per star as the pencil beams choose them
   (:func:`~mcsweep.experiments.f90_sweep.pencil_beam.case_geometry`). A star with fewer groups
   than a case needs is not in that case.
3. *Truth.* Position zero at the reference epoch, the Hipparcos parallax and proper
   motion (``truth = hipparcos``); and, to see what Hipparcos' own errors do, the same
   stars with the truth perturbed by N(0, e_Plx), N(0, e_pmRA), N(0, e_pmDE)
   (``truth = perturbed``, stream ``(43, 3, block)``) and the same measurement noise, so
   the difference between the two is a paired one.
4. *Solutions.* AL (and AC) measurements of the noise model (stream ``(43, 2, crc32(case),
   block)``), the reference epoch of ``observations.reference_epoch`` (``mean``: each
   star's mean epoch of its case's transits, Sect. 2.1), solved with the Eq. 18 prior
   ``factor`` x sigma_F90 of every prior: the paper's (Eqs. 14-17) and, with
   ``f90_formula=RUN_DIR``, a sweep run's fitted one (:meth:`mcsweep.prior.Prior.from_run`),
   and one per run of ``colour_priors`` (sweeps made with ``prior_model=colour`` or
   ``colour_mean``, named by that): queried with each star's Gaia DR3 BP-RP (the bundled
   match, :func:`~mcsweep.population.gaia_bright.hipparcos_match`; no colour gives the
   run's colour-blind prior) and, where the run has a mean, centred on the run's mean
   parallax and proper motion at the star: the prior's right-hand side ``N_p m`` of
   Eqs. 11-12 (:func:`~mcsweep.astrometry.solve.solve_with_prior` with ``prior_mean``),
   which gives the same position error as the zero-centred prior for a star whose truth is
   (truth - m). A star whose mean is not finite is not solved with that prior.
   Inside the P ellipse by :func:`mcsweep.astrometry.confidence.inside`.
5. *Table.* ``real_sky.csv``: per prior, truth, case, |b| band (0-15, 15-35, 35-90 deg;
   and all) and G bin (6-7, 7-8, 8-9; and all) the fraction inside with its
   Clopper-Pearson interval and the P-th percentile error with its order-statistic
   interval, each also per BP-RP bin (``colour_bin``: :data:`COLOUR_BINS` and 'all'; a
   star without a Gaia colour only in 'all') and for the G range :data:`TARGET_G` as one
   more G bin; ``real_sky_errors.csv``: Hipparcos' median parallax error against the median
   prior per band and G bin; ``real_sky_complete.csv``: the fractions carried over to the
   complete sky by colour (:mod:`mcsweep.experiments.real_sky.complete`).

Reproducibility: noise and perturbations are drawn per fixed block of
:data:`REAL_SKY_NOISE_BLOCK_STARS` stars, so chunking, workers and completion order change nothing.
"""

from __future__ import annotations

import dataclasses
import zlib

import numpy as np
import pandas as pd

from ...astrometry.confidence import inside as inside_ellipse
from ...astrometry.confidence import mahalanobis_sq, percentile_interval
from ...astrometry.design import design_matrix, years_since
from ...astrometry.measurements import simulate
from ...astrometry.solve import normal_equations, solve_with_prior
from ...errors import UserInputError
from ...population import gaia_bright
from ...population.hipparcos import EXTRA_MESSAGE, have_catalogue, load_hipparcos
from ...prior import Prior
from ...prior.run_record import read_record
from ...scanning import ScanningLaw, find_transits, observer_position_au
from ...astrometry.noise_models import noise_model
from ...scanning.timescale import tcb_jd
from ..global_solution.settings import GlobalSettings, spawn
from ..global_solution.table import FRACTION_INTERVAL, error_percentile, fraction_statistics

__all__ = ["TAG", "REAL_SKY_NOISE_BLOCK_STARS", "B_BANDS", "G_BINS", "TRUTHS", "COLOUR_BINS", "TARGET_G",
           "RealSkySettings", "build_settings", "load_prior", "colour_prior_name", "draw_stars", "prior_sigmas",
           "prior_queries", "star_columns", "solve_chunk", "table_rows", "error_rows", "table_markdown", "colour_markdown", "band_of",
           "gbin_of", "colour_bin_of"]

TAG = 43  # real-sky validation: first element of every spawn key (41: Sect. 4.1, 42: Sect. 4.2)
POPULATION_STREAM, NOISE_STREAM, PERTURB_STREAM = 0, 2, 3
#: Stars per noise block of the real-sky validation: the unit of randomness (noise and
#: perturbed truths) and of the per-star result store's chunks.
#: Why this size: a block's design arrays are padded to its most-observed star (stars x
#: most transits), so small blocks keep them small and waste little on padding, while
#: 1024 stars amortise the per-block seeding and NumPy call overhead. The value is part of
#: the results: it defines the noise streams (one per block) and the chunk boundaries
#: (chunks hold whole blocks), so a resumed run's finished chunks stay valid only with it;
#: it is fixed.
REAL_SKY_NOISE_BLOCK_STARS = 1024
#: |b| bands [deg] in which the validation's targets are stated (0-15, 15-35, above 35;
#: docs/galaxy_model.md).
B_BANDS = ((0.0, 15.0), (15.0, 35.0), (35.0, 90.0))
#: Truth variants (step 3 of the module notes).
TRUTHS = ("hipparcos", "perturbed")
#: BP-RP bins [mag] (name, lower edge, upper edge): close to the terciles of Gaia DR3's BP-RP
#: (Gaia Collaboration, Vallenari et al. 2023, A&A 674, A1) of the Hipparcos 2 stars of
#: G = 6-8 (0.55 and 1.22 mag by the bundled match): early types, F-K dwarfs, mostly giants.
COLOUR_BINS = (("blue", -np.inf, 0.56), ("middle", 0.56, 1.23), ("red", 1.23, np.inf))
#: The G range in which the real-sky targets are stated (docs/experiments/real_sky.md):
#: one more G bin of the table where it joins two or more of the 1-mag bins.
TARGET_G = (6.0, 8.0)


@dataclasses.dataclass(frozen=True, kw_only=True)
class RealSkySettings(GlobalSettings):
    """What a chunk needs besides its stars (picklable)."""

    #: name -> groups of every observation case solved.
    cases: tuple
    #: Multiplier of every prior's sigma_F90 (Eq. 18 with k sigma_F90).
    factor: float
    g_min: float
    g_max: float
    max_stars: int
    #: (name, source) of the priors: ('paper', 'paper') and, with f90_formula=RUN_DIR,
    #: ('fitted', RUN_DIR), then one (prior_model name, RUN_DIR) per colour prior; loaded
    #: by :func:`load_prior` in the parent (a Prior holds a mapping proxy, which does not
    #: pickle, and the tasks need only its values).
    priors: tuple
    #: Names of the priors queried with each star's BP-RP (the colour priors).
    colour: tuple = ()
    #: Names of the priors centred on a mean (their stars carry ``mean_*_<name>``).
    with_mean: tuple = ()


def band_of(b_deg) -> np.ndarray:
    """Index of the |b| band of :data:`B_BANDS` (|b| = 90 in the last)."""
    ab = np.abs(np.asarray(b_deg, dtype=float))
    return np.clip(np.searchsorted([hi for _, hi in B_BANDS[:-1]], ab, side="right"), 0, len(B_BANDS) - 1)


def g_bins(g_min: float, g_max: float) -> tuple:
    """1-mag G bins from g_min to g_max (the last may be shorter)."""
    edges = list(np.arange(g_min, g_max, 1.0)) + [g_max]
    return tuple(zip(edges[:-1], edges[1:]))


G_BINS = g_bins(6.0, 9.0)


def gbin_of(g, bins) -> np.ndarray:
    return np.clip(np.searchsorted([hi for _, hi in bins[:-1]], np.asarray(g, float), side="right"), 0,
                   len(bins) - 1)


def colour_bin_of(bp_rp) -> np.ndarray:
    """Index of the BP-RP bin of :data:`COLOUR_BINS`; -1 without a colour (NaN)."""
    c = np.asarray(bp_rp, dtype=float)
    out = np.searchsorted([hi for _, _, hi in COLOUR_BINS[:-1]], c, side="right")
    return np.where(np.isfinite(c), out, -1)


def colour_prior_name(run_dir) -> str:
    """The prior_model name of a sweep run made with a colour axis or a mean (from its
    record, :func:`mcsweep.prior.run_record.read_record`); a
    :class:`~mcsweep.errors.UserInputError` in one line otherwise."""
    expected = "expected the directory of a sweep run made with prior_model=colour or prior_model=colour_mean"
    try:
        record = read_record(run_dir, expected)
    except UserInputError as exc:
        raise UserInputError(f"experiment.real_sky.colour_priors: {run_dir} is not accepted ({exc})") from None
    if not (record.colour_edges or record.mean):
        raise UserInputError(f"experiment.real_sky.colour_priors: {run_dir} is not accepted (prior_model "
                             f"{record.prior_model_name!r}); {expected}")
    return record.prior_model_name


def build_settings(config) -> RealSkySettings:
    """Settings from a checked config; user errors (no extra, bad run directory) raised here."""
    if not have_catalogue():
        raise UserInputError(EXTRA_MESSAGE)
    sec = config.experiment.real_sky
    obs = config.observations
    unknown = [c for c in sec.cases if c not in obs.cases]
    if unknown:
        raise UserInputError(f"experiment.real_sky.cases={list(sec.cases)} is not accepted; expected cases of "
                             f"observations.cases ({', '.join(obs.cases)})")
    start_jd = tcb_jd(str(obs.start), "observations.start")
    end_jd = tcb_jd(str(obs.end), "observations.end")
    # Sect. 2.1: 'mean' refers each star to the mean epoch of its (case's) observations.
    epoch = "star_mean" if obs.reference_epoch == "mean" else str(obs.fixed_epoch)
    priors = [("paper", "paper")]
    if sec.f90_formula != "paper":
        load_prior(sec.f90_formula)  # a bad run directory is a user error now, before any output
        priors.append(("fitted", str(sec.f90_formula)))
    colour, with_mean = [], []
    for run_dir in sec.colour_priors:
        name = colour_prior_name(run_dir)
        taken = {p for p, _ in priors}
        label = name if name not in taken else next(f"{name}_{k}" for k in range(2, len(priors) + 2)
                                                    if f"{name}_{k}" not in taken)
        prior = load_prior(str(run_dir))  # a bad run directory is a user error now
        priors.append((label, str(run_dir)))
        colour.append(label)
        if prior.has_mean:
            with_mean.append(label)
    return RealSkySettings(
        seed=int(config.seed), start_jd=start_jd, end_jd=end_jd,
        law=ScanningLaw.from_config(dataclasses.asdict(config.scanning)), noise=noise_model(config.noise),
        confidence=float(config.confidence), ratio_R=float(config.ratio_R), reference_epoch=epoch,
        cases=tuple((c, tuple(int(g) for g in obs.cases[c])) for c in sec.cases), factor=float(sec.factor),
        g_min=float(sec.g_min), g_max=float(sec.g_max), max_stars=int(sec.max_stars), priors=tuple(priors),
        colour=tuple(colour), with_mean=tuple(with_mean))


def load_prior(source: str) -> Prior:
    """The paper's prior (Eqs. 14-17) for 'paper', else a sweep run's fit (Prior.from_run)."""
    return Prior.paper() if source == "paper" else Prior.from_run(source)


def draw_stars(settings: RealSkySettings) -> pd.DataFrame:
    """The Hipparcos stars of the G range (with ``max_stars``: an unbiased seeded subset,
    file order kept), with ``bp_rp``: Gaia DR3's BP-RP of the star's counterpart (NaN
    without one); ``attrs['n_in_range']`` is the number before the subset."""
    df = load_hipparcos().assign(bp_rp=gaia_bright.hipparcos_match().hip_bp_rp)
    g = df["phot_g_mean_mag"].to_numpy()
    df = df[(g >= settings.g_min) & (g < settings.g_max)].reset_index(drop=True)
    n = len(df)
    if settings.max_stars and n > settings.max_stars:
        rng = np.random.default_rng(spawn(settings.seed, TAG, POPULATION_STREAM, 0))
        df = df.iloc[np.sort(rng.choice(n, settings.max_stars, replace=False))].reset_index(drop=True)
    df.attrs["n_in_range"] = n
    return df


def prior_sigmas(settings: RealSkySettings, stars: pd.DataFrame) -> dict[str, np.ndarray]:
    """sigma_F90 [mas] of every prior at each star (before ``factor``)."""
    return {k[len("sigma_"):]: v for k, v in prior_queries(settings, stars).items() if k.startswith("sigma_")}


def prior_queries(settings: RealSkySettings, stars: pd.DataFrame) -> dict[str, np.ndarray]:
    """The star columns of every prior: ``sigma_<prior>`` (sigma_F90 [mas], before
    ``factor``) and, for a prior with a mean, ``mean_parallax_<prior>`` [mas] and
    ``mean_pmra_<prior>``, ``mean_pmdec_<prior>`` [mas/yr, ICRS, pmra = mu_alpha*]. A colour
    prior is queried with the star's ``bp_rp`` (NaN: the run's colour-blind prior)."""
    l, b, g = (stars[c].to_numpy(float) for c in ("l", "b", "phot_g_mean_mag"))
    bp_rp = stars["bp_rp"].to_numpy(float) if "bp_rp" in stars else np.full(len(stars), np.nan)
    out = {}
    for name, src in settings.priors:
        prior = load_prior(src)
        if name not in settings.colour:
            out[f"sigma_{name}"] = np.asarray(prior.sigma_parallax_mas(l, b, g), float)
            continue
        out[f"sigma_{name}"] = np.asarray(prior.sigma_parallax_mas(l, b, g, bp_rp=bp_rp), float)
        if name in settings.with_mean:
            pmra, pmdec = prior.mean_pm_masyr(l, b, g, bp_rp=bp_rp)
            out[f"mean_parallax_{name}"] = np.asarray(prior.mean_parallax_mas(l, b, g, bp_rp=bp_rp), float)
            out[f"mean_pmra_{name}"], out[f"mean_pmdec_{name}"] = np.asarray(pmra, float), np.asarray(pmdec, float)
    return out


def star_columns(settings: RealSkySettings) -> list[str]:
    """The prior columns a chunk needs besides the stars' own (:func:`prior_queries`)."""
    cols = [f"sigma_{p}" for p, _ in settings.priors]
    for p in settings.with_mean:
        cols += [f"mean_parallax_{p}", f"mean_pmra_{p}", f"mean_pmdec_{p}"]
    return cols


# --------------------------------------------------------------------------- solutions
def case_rows(src: np.ndarray, group: np.ndarray, n: int, groups: tuple) -> tuple[np.ndarray, np.ndarray]:
    """(rows kept, stars having the case) for one case: per star the distinct-transit groups
    ``groups`` (negative = from the last), as :func:`pencil_beam.case_geometry` picks them."""
    n_groups = np.zeros(n, dtype=np.int64)
    np.maximum.at(n_groups, src, group.astype(np.int64) + 1)
    chosen = np.stack([np.where(np.int64(g) >= 0, g, n_groups + g) for g in groups])  # (len(groups), n)
    ok = np.all((chosen >= 0) & (chosen < n_groups), axis=0)
    if len(groups) > 1:  # the case's groups must be distinct visits of the star (vectorised over stars)
        ok &= np.all(np.diff(np.sort(chosen, axis=0), axis=0) != 0, axis=0)
    keep = np.zeros(src.size, dtype=bool)
    for row in chosen:
        keep |= group == row[src]
    return keep & ok[src], ok


def _padded(src, cols: dict, keep: np.ndarray, stars_sel: np.ndarray):
    """Padded (n_sel, k) arrays of the kept rows of the stars ``stars_sel``."""
    idx = np.flatnonzero(keep & np.isin(src, stars_sel))
    s = src[idx]
    pos = np.searchsorted(stars_sel, s)
    counts = np.bincount(pos, minlength=stars_sel.size)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    col = np.arange(idx.size) - first[pos]
    k = max(1, int(counts.max()) if counts.size else 1)
    shape = (stars_sel.size, k)
    t, psi = np.full(shape, np.nan), np.full(shape, np.nan)
    obs, mask = np.full(shape + (3,), np.nan), np.zeros(shape, dtype=bool)
    t[pos, col], psi[pos, col], obs[pos, col], mask[pos, col] = (cols["t"][idx], cols["psi"][idx],
                                                                 cols["obs"][idx], True)
    return t, psi, obs, mask


def solve_chunk(settings: RealSkySettings, first: int, stars: dict) -> pd.DataFrame:
    """Per-star results of the stars ``first, first + 1, ...`` (module notes, steps 2-4).

    ``stars``: ``ra, dec, l, b, phot_g_mean_mag, parallax, pmra, pmdec`` and their
    ``*_error``, ``hip``, ``sigma_<prior>`` (sigma_F90 [mas] of each prior) and, for the
    priors of ``settings.with_mean``, their means (:func:`prior_queries`). One row
    per star: ``star``, ``hip``, ``n_groups``; per case ``n_fov_<case>``; per case, truth
    and prior ``inside_<case>_<truth>_<prior>`` (1/0, -1 = not in the case or no region)
    and ``err_<case>_<truth>_<prior>_mas``.
    """
    if first % REAL_SKY_NOISE_BLOCK_STARS:
        raise ValueError(f"first={first} must be a multiple of REAL_SKY_NOISE_BLOCK_STARS={REAL_SKY_NOISE_BLOCK_STARS}")
    st = {c: np.asarray(v) for c, v in stars.items()}
    n = st["ra"].size
    tr = find_transits(st["ra"], st["dec"], settings.start_jd, settings.end_jd, law=settings.law)
    src = tr["source_index"].to_numpy().astype(np.int64)
    group = tr["group"].to_numpy()
    cols = {"t": tr["tcb_jd"].to_numpy(float), "psi": tr["scan_angle_deg"].to_numpy(float),
            "obs": observer_position_au(tr)}
    del tr
    n_groups = np.zeros(n, dtype=np.int64)
    np.maximum.at(n_groups, src, group.astype(np.int64) + 1)
    out = {"star": (first + np.arange(n)).astype(np.int32), "hip": st["hip"].astype(np.int64),
           "n_groups": n_groups.astype(np.int16)}
    truths = {}
    for lo in range(0, n, REAL_SKY_NOISE_BLOCK_STARS):
        hi = min(lo + REAL_SKY_NOISE_BLOCK_STARS, n)
        rng = np.random.default_rng(spawn(settings.seed, TAG, PERTURB_STREAM, (first + lo) // REAL_SKY_NOISE_BLOCK_STARS))
        z = rng.standard_normal((3, hi - lo))
        truths.setdefault("perturbed", []).append(np.stack(
            [st["parallax"][lo:hi] + z[0] * st["parallax_error"][lo:hi],
             st["pmra"][lo:hi] + z[1] * st["pmra_error"][lo:hi],
             st["pmdec"][lo:hi] + z[2] * st["pmdec_error"][lo:hi]], axis=1))
    x_truth = {"hipparcos": np.stack([st["parallax"], st["pmra"], st["pmdec"]], axis=1),
               "perturbed": np.concatenate(truths["perturbed"]) if n else np.empty((0, 3))}
    for case, groups in settings.cases:
        keep, has = case_rows(src, group, n, groups)
        out[f"n_fov_{case}"] = np.bincount(src[keep], minlength=n).astype(np.int16)
        res = {(truth, p): (np.full(n, -1, np.int8), np.full(n, np.nan, np.float32))
               for truth in TRUTHS for p, _ in settings.priors}
        for lo in range(0, n, REAL_SKY_NOISE_BLOCK_STARS):
            hi = min(lo + REAL_SKY_NOISE_BLOCK_STARS, n)
            sel = lo + np.flatnonzero(has[lo:hi])
            if sel.size == 0:
                continue
            t, psi, obs, mask = _padded(src, cols, keep, sel)
            t_yr = years_since(t, settings.epoch_tcb_jd(t, mask))
            s_al, s_ac = settings.noise.design_sigmas(st["phot_g_mean_mag"][sel])
            A = design_matrix(st["ra"][sel], st["dec"][sel], t_yr, psi, obs, sigma_al_mas=s_al,
                              sigma_ac_mas=s_ac, mask=mask)
            seed = spawn(settings.seed, TAG, NOISE_STREAM, zlib.crc32(case.encode()), (first + lo) // REAL_SKY_NOISE_BLOCK_STARS)
            noise = np.random.default_rng(seed)
            # One noise realisation per block and case, shared by both truths and all priors.
            zeros = np.zeros((sel.size, 5))
            h0 = simulate(A, zeros, noise, mask=mask)
            for truth in TRUTHS:
                x = zeros.copy()
                x[:, 2:] = x_truth[truth][sel]
                h = h0 + np.einsum("nmk,nk->nm", A, x)
                N0, b0 = normal_equations(A, h)
                for p, _ in settings.priors:
                    mean, no_mean = None, np.zeros(sel.size, bool)
                    if p in settings.with_mean:
                        # centred on m (Eqs. 11-12; module notes, step 4); m has no position part
                        mean = np.zeros((sel.size, 5))
                        mean[:, 2:] = np.stack([st[f"mean_{k}_{p}"][sel] for k in ("parallax", "pmra", "pmdec")],
                                               axis=1)
                        no_mean = ~np.all(np.isfinite(mean), axis=1)
                        mean[no_mean] = 0.0
                    sol = solve_with_prior(N0, b0, settings.factor * st[f"sigma_{p}"][sel], settings.ratio_R,
                                           prior_mean=mean)
                    dpos, cov = sol.position, sol.position_cov  # true position offset is zero
                    ok = sol.ok & ~no_mean & np.isfinite(mahalanobis_sq(dpos, cov))
                    flags, err = res[(truth, p)]
                    flags[sel[ok]] = inside_ellipse(dpos[ok], cov[ok], settings.confidence)
                    err[sel[ok]] = np.hypot(dpos[ok, 0], dpos[ok, 1])
        for (truth, p), (flags, err) in res.items():
            out[f"inside_{case}_{truth}_{p}"], out[f"err_{case}_{truth}_{p}_mas"] = flags, err
    return pd.DataFrame(out)


# --------------------------------------------------------------------------- tables
def _label(lo: float, hi: float) -> str:
    return f"{lo:g}-{hi:g}"


def g_sets(g, g_min: float, g_max: float) -> list[tuple[str, np.ndarray]]:
    """(label, mask) of the G bins of the table: the 1-mag bins, :data:`TARGET_G` where it
    joins two or more of them but not all, and 'all'."""
    bins = g_bins(g_min, g_max)
    gbin = gbin_of(g, bins)
    out = [(_label(*bins[j]), gbin == j) for j in range(len(bins))]
    joined = [j for j, (lo, hi) in enumerate(bins) if TARGET_G[0] <= lo and hi <= TARGET_G[1]]
    if (len(joined) > 1 and len(joined) < len(bins) and bins[joined[0]][0] == TARGET_G[0]
            and bins[joined[-1]][1] == TARGET_G[1]):
        out.append((_label(*TARGET_G), np.isin(gbin, joined)))
    return out + [("all", np.ones(np.size(g), bool))]


def table_rows(stars: pd.DataFrame, results: pd.DataFrame, settings: RealSkySettings) -> pd.DataFrame:
    """``real_sky.csv``: one row per prior x truth x case x |b| band x G bin x BP-RP bin
    (each also 'all'; the G bins with :data:`TARGET_G`, :func:`g_sets`)."""
    p = settings.confidence
    q = error_percentile(p)
    band = band_of(stars["b"].to_numpy())
    cbin = colour_bin_of(stars["bp_rp"].to_numpy(float) if "bp_rp" in stars else np.full(len(stars), np.nan))
    groups = [(_label(*B_BANDS[i]), band == i) for i in range(len(B_BANDS))] + [("all", np.ones(len(stars), bool))]
    gsets = g_sets(stars["phot_g_mean_mag"].to_numpy(), settings.g_min, settings.g_max)
    csets = [("all", np.ones(len(stars), bool))] + [(name, cbin == k) for k, (name, _, _) in enumerate(COLOUR_BINS)]
    rows = []
    for prior, _ in settings.priors:
        for truth in TRUTHS:
            for case, _ in settings.cases:
                flags = results[f"inside_{case}_{truth}_{prior}"].to_numpy()
                err = results[f"err_{case}_{truth}_{prior}_mas"].to_numpy()
                for bname, bmask in groups:
                    for gname, gmask in gsets:
                        for cname, cmask in csets:
                            m = bmask & gmask & cmask
                            n_valid, n_in, frac, lo, hi = fraction_statistics(flags[m])
                            e = err[m & (flags >= 0)]
                            pe = float(np.percentile(e, q)) if e.size else float("nan")
                            elo, ehi = percentile_interval(e, q, FRACTION_INTERVAL) if e.size else (np.nan, np.nan)
                            rows.append({"prior": prior, "truth": truth, "case": case, "b_band_deg": bname,
                                         "g_bin": gname, "colour_bin": cname, "n_stars": int(m.sum()),
                                         "n_valid": n_valid, "n_inside": n_in, "fraction_inside": frac,
                                         "fraction_lo": lo, "fraction_hi": hi, "p_error_mas": pe,
                                         "p_error_lo_mas": elo, "p_error_hi_mas": ehi})
    return pd.DataFrame(rows)


def error_rows(stars: pd.DataFrame, settings: RealSkySettings) -> pd.DataFrame:
    """``real_sky_errors.csv``: per |b| band x G bin, Hipparcos' median e_Plx against the
    median sigma_F90 of each prior (times ``factor``), and their ratio."""
    bins = g_bins(settings.g_min, settings.g_max)
    band = band_of(stars["b"].to_numpy())
    gbin = gbin_of(stars["phot_g_mean_mag"].to_numpy(), bins)
    rows = []
    for i, bb in enumerate(B_BANDS):
        for j, gb in enumerate(bins):
            m = (band == i) & (gbin == j)
            row = {"b_band_deg": _label(*bb), "g_bin": _label(*gb), "n_stars": int(m.sum()),
                   "median_parallax_error_mas": float(np.median(stars["parallax_error"][m])) if m.any() else np.nan,
                   "median_abs_parallax_mas": float(np.median(np.abs(stars["parallax"][m]))) if m.any() else np.nan}
            for prior, _ in settings.priors:
                s = settings.factor * stars[f"sigma_{prior}"].to_numpy()[m]
                row[f"median_sigma_{prior}_mas"] = float(np.median(s)) if m.any() else np.nan
                row[f"error_over_sigma_{prior}"] = (row["median_parallax_error_mas"] / row[f"median_sigma_{prior}_mas"]
                                                    if m.any() else np.nan)
            rows.append(row)
    return pd.DataFrame(rows)


def colour_cell(r) -> str:
    """'fraction [interval] / P-th percentile error (n)' of a row of ``real_sky.csv``."""
    if not np.isfinite(r["fraction_inside"]):
        return "–"
    return (f"{100 * r['fraction_inside']:.1f} [{100 * r['fraction_lo']:.1f}-{100 * r['fraction_hi']:.1f}] / "
            f"{r['p_error_mas']:.3g} (n={r['n_valid']})")


def colour_target_g(table: pd.DataFrame) -> str:
    """The G bin in which the BP-RP tables are shown: :data:`TARGET_G` where the table has
    it, else 'all'."""
    target = _label(*TARGET_G)
    return target if (table["g_bin"] == target).any() else "all"


def colour_markdown(table: pd.DataFrame, confidence: float) -> list[str]:
    """The section of ``real_sky.md`` per |b| band x BP-RP bin: per case, G bin
    :func:`colour_target_g` and truth = Hipparcos, one row per prior and band."""
    if "colour_bin" not in table or not (table["colour_bin"] != "all").any():
        return []
    pct = f"{100 * confidence:g}"
    gname = colour_target_g(table)
    part = table[(table["truth"] == "hipparcos") & (table["g_bin"] == gname)]
    cnames = ["all"] + [c for c, _, _ in COLOUR_BINS]
    edges = ", ".join(f"{c} {'<' if np.isinf(lo) else f'{lo:g} <='} BP-RP" + ("" if np.isinf(hi) else f" < {hi:g}")
                      for c, lo, hi in COLOUR_BINS)
    lines = [f"## Per |b| band x Gaia BP-RP bin, G {gname}: in {pct} % ellipse [%] / p{pct} error [mas]", "",
             f"BP-RP bins: {edges} (Gaia DR3 colours of the stars' counterparts; stars without one only "
             "in 'all').", ""]
    for case in dict.fromkeys(part["case"]):
        sub = part[part["case"] == case]
        lines += [f"### Case '{case}'", ""]
        head = ["prior", "abs(b) band [deg]"] + [f"BP-RP {c}" for c in cnames]
        lines += ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
        for prior in dict.fromkeys(sub["prior"]):
            for bname in dict.fromkeys(sub["b_band_deg"]):
                cell = sub[(sub["prior"] == prior) & (sub["b_band_deg"] == bname)].set_index("colour_bin")
                lines.append("| " + " | ".join([prior, bname] + [colour_cell(cell.loc[c]) for c in cnames]) + " |")
        lines.append("")
    return lines


def table_markdown(table: pd.DataFrame, errors: pd.DataFrame, settings: RealSkySettings, notes) -> str:
    """``real_sky.md``: per prior and case, fraction inside [interval] and P-th percentile
    error per |b| band (rows) and G bin (columns), truth = Hipparcos; then Hipparcos' errors."""
    pct = f"{100 * settings.confidence:g}"
    lines = ["# Real-sky validation: Hipparcos 2 stars as truth", ""] + list(notes) + [""]
    part = table[(table["truth"] == "hipparcos") & (table.get("colour_bin", "all") == "all")]
    gnames = list(dict.fromkeys(part["g_bin"]))
    for prior, _ in settings.priors:
        for case, _ in settings.cases:
            sub = part[(part["prior"] == prior) & (part["case"] == case)]
            lines += [f"## Prior '{prior}', case '{case}': in {pct} % ellipse [%] / p{pct} error [mas]", ""]
            head = ["abs(b) band [deg]"] + [f"G {g}" for g in gnames]
            lines += ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
            for bname in dict.fromkeys(sub["b_band_deg"]):
                cells = []
                for g in gnames:
                    r = sub[(sub["b_band_deg"] == bname) & (sub["g_bin"] == g)].iloc[0]
                    cells.append("–" if not np.isfinite(r["fraction_inside"]) else
                                 f"{100 * r['fraction_inside']:.1f} [{100 * r['fraction_lo']:.1f}-"
                                 f"{100 * r['fraction_hi']:.1f}] / {r['p_error_mas']:.3g} (n={r['n_valid']})")
                lines.append("| " + " | ".join([bname] + cells) + " |")
            lines.append("")
    lines += colour_markdown(table, settings.confidence)
    lines += ["## Hipparcos' own parallax errors against the prior", "",
              "| " + " | ".join(errors.columns) + " |", "|" + "|".join("---" for _ in errors.columns) + "|"]
    lines += ["| " + " | ".join(f"{v:.3g}" if isinstance(v, float) else str(v) for v in row) + " |"
              for row in errors.itertuples(index=False)]
    return "\n".join(lines) + "\n"
