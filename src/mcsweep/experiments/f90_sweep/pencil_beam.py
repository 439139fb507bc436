"""One pencil-beam cell: the sigma_F90 search of paper Sects. 3.2-3.4.

For one direction and one G bin: draw the stars of the beam, take the direction's
field-of-view transits, and for each observation case (Fig. 3: 1, 2, 2 diluted, 4 and
8 distinct transits) simulate AL/AC measurements and solve with every prior of a log
grid (Eqs. 9-13, 18). Per prior the cell records the fraction of actual position
errors inside the P-confidence ellipse (Sect. 2.4), the P-th percentile of the actual
errors and the median semi-major axis (Figs. 1 and 3). sigma_F90 is the smallest prior
whose fraction reaches P in the two-transit case (Sect. 3.3); every case is then also
evaluated at that prior, as in Fig. 3.

All stars of a cell are observed with the transits of the beam's centre. Beam rule
(:func:`cell_radius`): with the built-in galaxy model the beam keeps the paper's 1 deg
and at least ``min_stars`` stars are drawn from its density; with a catalogue the beam
is widened until it holds ``min_stars`` (:func:`beam_radius`).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import pyarrow as pa

from ...astrometry.confidence import ellipse_semi_axes, inside, inside_counts, mahalanobis_sq
from ...astrometry.design import JULIAN_YEAR_DAYS, design_matrix, reference_epoch
from ...astrometry.noise_models import NoiseModelLike
from ...astrometry.prior_scan import MAX_KEY_PRIORS, PriorScan, prior_scan
from ...astrometry.shared_design import SharedDesignNormals
from ...astrometry.solve import solve_with_prior
from ...galactic import pm_galactic_from_icrs, pm_icrs_from_galactic
from ...renamed_names import old_names
from ...runtime.store import table_from_columns
from ...scanning import observer_position_au
from ..f90_curve import flag_patterns, ill_determined, key_patterns, pattern_interval, sigma_f90_from_curve

__all__ = [
    "CellSettings",
    "CaseGeometry",
    "beam_radius",
    "cell_radius",
    "case_geometry",
    "prior_curve",
    "scan_curve",
    "run_cell",
    "transit_columns",
    "cell_stars",
    "cell_normals",
    "cell_mean",
    "CURVE_COLUMNS",
    "COLOUR_COLUMNS",
    "CELL_MEAN_COLUMNS",
    "curve_columns",
]

_STAR_STREAM, _NOISE_STREAM, _BOOTSTRAP_STREAM, _MEAN_STREAM, _QUASAR_STREAM = 0, 1, 2, 3, 4
#: The colour cells' batches (:class:`ColourBatches`): a sub-stream of the star and mean streams.
COLOUR_BATCH_STREAM = 5

#: A colour cell takes the stars of its BP-RP bin from batches of ``min_stars`` drawn for its
#: direction x G bin (:class:`ColourBatches`), up to this many batches: a bin holding under
#: 1/COLOUR_DRAW_BATCHES of the stars gets fewer than ``min_stars``.
COLOUR_DRAW_BATCHES = 10
#: Below this many stars a colour cell's sigma_F90 is not determined (flag ``few_stars``): the
#: binomial standard error of its fraction inside would exceed 1 point at P = 0.9.
COLOUR_MIN_STARS = 1000

#: Columns of a cell's result table (one row per case x prior).
CURVE_COLUMNS = [
    "cell_id", "l_deg", "b_deg", "ra_deg", "dec_deg", "g_min", "g_max", "case",
    "sigma_prior_mas", "at_f90", "fraction_inside", "n_inside", "n_valid", "p_error_mas",
    "median_semi_major_mas", "n_stars", "n_in_cone", "radius_deg", "n_groups", "sigma_f90_mas", "f90_flag",
    "sigma_f90_lo_mas", "sigma_f90_hi_mas", "ill_determined",
]
#: Added to :data:`CURVE_COLUMNS` with the colour axis (NaN for the colour-blind cells).
COLOUR_COLUMNS = ["bp_rp_min", "bp_rp_max"]
#: Added with a mean-centred prior: the cell's mean (the prior's centre; proper motion in
#: galactic and in ICRS components at the beam centre) and, at sigma_F90 of the F90 case, what
#: that prior does to sources with zero parallax and proper motion (quasars).
CELL_MEAN_COLUMNS = ["mean_parallax_mas", "mean_pml_masyr", "mean_pmb_masyr", "mean_pmra_masyr", "mean_pmdec_masyr",
                "n_mean_stars", "quasar_fraction_inside", "quasar_n_valid", "quasar_p_error_mas"]


def curve_columns(s: "CellSettings") -> list[str]:
    """The columns of a cell's table under settings ``s``."""
    return CURVE_COLUMNS + (COLOUR_COLUMNS if s.colour_axis else []) + (CELL_MEAN_COLUMNS if s.mean else [])


@dataclass(frozen=True)
class CellSettings:
    """Everything a cell needs besides its identity (picklable, shared by all cells)."""

    prior_grid_mas: tuple[float, ...]
    cases: dict[str, tuple[int, ...]]
    f90_case: str
    confidence: float
    ratio_R: float
    beam_radius_deg: float
    max_stars: int
    min_stars: int
    max_radius_deg: float
    interpolation: str
    reference_epoch: str
    fixed_epoch_tcb_jd: float
    noise: NoiseModelLike
    seed: int
    #: Bootstrap resamples of the stars for the sigma_F90 interval (0 = no interval).
    n_bootstrap: int = 0
    #: Priors at which to keep every star's error and covariance (Fig. 2); F90 is added.
    scatter_priors_mas: tuple[float, ...] = field(default=())
    #: p_error_mas and median_semi_major_mas at every prior of the grid (True), or only
    #: at sigma_F90 (False): on the grid only the showcase's figures use them, and they
    #: cost more than the fraction inside (two partial sorts per prior).
    grid_statistics: bool = True
    #: The sweep has a colour axis (:class:`~mcsweep.experiments.f90_sweep.conf.PriorModelConf`):
    #: every cell's table carries :data:`COLOUR_COLUMNS`.
    colour_axis: bool = False
    #: Centre the prior on the cell's mean parallax and proper motion (:data:`CELL_MEAN_COLUMNS`).
    mean: bool = False


@dataclass(frozen=True)
class CaseGeometry:
    """The transits of one observation case at the beam centre."""

    tcb_jd: np.ndarray
    psi_deg: np.ndarray
    obs_au: np.ndarray  # (k, 3)


def _cap_area(radius_deg: float) -> float:
    return 2.0 * math.pi * (1.0 - math.cos(math.radians(radius_deg)))


def beam_radius(source, l_deg, b_deg, g_min, g_max, *, radius_deg: float, min_stars: int,
                max_radius_deg: float) -> tuple[float, float]:
    """Radius reaching ``min_stars`` expected stars, and that expected count.

    The 1 deg beam of Table 1 holds only ~10-80 stars at G < 10, too few to measure a
    90 % fraction, so the beam is widened around the same centre (solid angle scaled by
    the deficit, re-evaluated twice because the density changes across a wide beam).
    """
    radius = radius_deg
    expected = float(source.expected_count(l_deg, b_deg, radius, g_min, g_max))
    for _ in range(3):
        if expected >= min_stars or radius >= max_radius_deg:
            break
        if expected <= 0:
            radius = max_radius_deg
        else:
            area = _cap_area(radius) * min_stars / expected * 1.05
            cos_r = max(1.0 - area / (2.0 * math.pi), math.cos(math.radians(max_radius_deg)))
            radius = min(math.degrees(math.acos(cos_r)), max_radius_deg)
        expected = float(source.expected_count(l_deg, b_deg, radius, g_min, g_max))
    return radius, expected


def cell_radius(source, cell, s: CellSettings) -> tuple[float, float]:
    """Beam radius of a cell and the expected number of stars in it.

    Beam rule: a source that can draw from its density (the built-in galaxy model,
    ``draws_from_density``) keeps the paper's beam (Table 1: 1 deg) and draws at least
    ``min_stars`` stars from it -- independent realisations of the same distribution;
    a catalogue has no further stars, so its beam is widened (:func:`beam_radius`).
    """
    d = cell.direction
    if getattr(source, "draws_from_density", False):
        return s.beam_radius_deg, float(source.expected_count(d.l_deg, d.b_deg, s.beam_radius_deg,
                                                              cell.g_min, cell.g_max))
    return beam_radius(source, d.l_deg, d.b_deg, cell.g_min, cell.g_max, radius_deg=s.beam_radius_deg,
                       min_stars=s.min_stars, max_radius_deg=s.max_radius_deg)


def transit_columns(transits: pd.DataFrame | dict) -> dict:
    """The columns of a direction's transits the cases need, as numpy arrays; what
    :func:`run_cell` takes in place of the table (the sweep makes them once per direction, not
    per cell: the observer positions cost 0.9 ms). Given such a dict, returns it."""
    if isinstance(transits, dict):
        return transits
    return {"group": transits["group"].to_numpy(), "tcb_jd": transits["tcb_jd"].to_numpy(float),
            "scan_angle_deg": transits["scan_angle_deg"].to_numpy(float),
            "obs_au": observer_position_au(transits)}


def case_geometry(transits: pd.DataFrame | dict, groups: tuple[int, ...]) -> CaseGeometry | None:
    """Transits of the requested distinct-transit groups (negative = from the last).

    ``transits``: the FoV transits of a direction, or the arrays of
    :func:`transit_columns` made from them. Returns None when the direction has fewer
    groups than the case asks for.
    """
    cols = transit_columns(transits)
    group = cols["group"]
    available = np.unique(group)
    try:
        chosen = available[list(groups)]
    except IndexError:
        return None
    if len(np.unique(chosen)) < len(groups):
        return None  # e.g. "first and last" with a single group
    idx = np.flatnonzero(np.isin(group, chosen))
    tcb = cols["tcb_jd"][idx]
    order = np.argsort(tcb, kind="stable")
    idx = idx[order]
    return CaseGeometry(tcb_jd=tcb[order], psi_deg=cols["scan_angle_deg"][idx], obs_au=cols["obs_au"][idx])


def _weights_and_truth(stars: pd.DataFrame, s: CellSettings) -> tuple[list, np.ndarray]:
    """Each star's 1 / sigma per block of rows (AL, then AC; the noise model's, by G) and its
    true parallax and proper motion (3, n): the same in every observation case of a cell."""
    g = stars["phot_g_mean_mag"].to_numpy(float)
    weights = [1.0 / s.noise.sigma_al_mas(g)] + ([1.0 / s.noise.sigma_ac_mas(g)] if s.noise.use_ac else [])
    truth = np.stack([stars[c].to_numpy(float) for c in ("parallax", "pmra", "pmdec")])  # x_true[2:], Sect. 3.2
    return weights, truth


def cell_normals(geom: CaseGeometry, ra_deg, dec_deg, stars: pd.DataFrame, s: CellSettings,
                 rng: np.random.Generator, *, weights_and_truth: tuple | None = None) -> SharedDesignNormals:
    """Normal equations (Eqs. 2-3) of every star of the cell, in factored form.

    All stars of a cell are observed with the transits of the beam centre, so their
    design matrices differ only by the per-star uncertainties, and the measurement noise
    is drawn in the normal equations' own space (:mod:`mcsweep.astrometry.shared_design`):
    ``N0`` equals ``design_matrix`` + ``normal_equations`` to rounding, and ``b0 - N0 x``
    has the distribution that ``simulate`` gives it. ``weights_and_truth``: what
    ``_weights_and_truth(stars, s)`` gives, if the caller has it (one cell's cases share it).
    """
    k = len(geom.tcb_jd)
    tcb = geom.tcb_jd[None, :]
    if s.reference_epoch == "mean":
        t_ep = reference_epoch(tcb, np.ones((1, k), dtype=bool))  # Sect. 2.1: mean epoch of observation
    else:
        t_ep = np.full(1, s.fixed_epoch_tcb_jd)
    t_yr = (tcb - t_ep[:, None]) / JULIAN_YEAR_DAYS
    use_ac = s.noise.use_ac
    a1 = design_matrix(np.array([ra_deg], float), np.array([dec_deg], float), t_yr, geom.psi_deg[None, :],
                       geom.obs_au[None, :, :], sigma_al_mas=1.0, sigma_ac_mas=1.0 if use_ac else None)[0]
    weights, truth = _weights_and_truth(stars, s) if weights_and_truth is None else weights_and_truth
    return SharedDesignNormals.simulate(a1, weights, truth, rng)


def _evaluate(normals: SharedDesignNormals, sigma_mas: float, s: CellSettings):
    sol = solve_with_prior(*normals.matrices(), sigma_mas, ratio_R=s.ratio_R)
    # True position offsets are zero at the reference epoch, so x[:, :2] are the
    # actual position errors (estimated minus true), Sect. 3.2.
    dpos = sol.x[:, :2]
    cov2 = sol.cov[:, :2, :2]
    return dpos, cov2


def scan_curve(scan: PriorScan, priors_mas, s: CellSettings, *, statistics: bool = True):
    """The table of :func:`prior_curve` from a prior scan, and the per-star flags.

    The fraction inside comes from :meth:`PriorScan.inside_flags` (no solution is
    formed); with ``statistics`` the P-th percentile of the actual errors and the
    median semi-major axis are computed from :meth:`PriorScan.position` at every prior
    (NaN otherwise: the sweep writes them only where a figure uses them).

    Returns
    -------
    table : pandas.DataFrame
    inside, valid : ndarray of bool, shape (n_priors, n_stars)
    """
    priors = np.atleast_1d(np.asarray(priors_mas, float))
    inside_flags, valid_flags = scan.inside_flags(priors, s.confidence)
    err, semi = _statistics(scan, priors, s) if statistics else (None, None)
    arrays = _curve_arrays(priors, np.count_nonzero(inside_flags, axis=1), np.count_nonzero(valid_flags, axis=1),
                           err, semi, s)
    return pd.DataFrame(arrays), inside_flags, valid_flags


def scan_arrays(scan: PriorScan, priors_mas, s: CellSettings, *, statistics: bool, patterns: bool = False):
    """The columns of :func:`scan_curve`'s table, and with ``patterns`` the stars' patterns of
    flags over the priors (:func:`mcsweep.experiments.f90_curve.flag_patterns`, for the
    bootstrap), else None; the per-star flags are never formed."""
    priors = np.atleast_1d(np.asarray(priors_mas, float))
    if patterns and len(priors) > MAX_KEY_PRIORS:
        inside_flags, valid_flags = scan.inside_flags(priors, s.confidence)
        n_in, n_valid = np.count_nonzero(inside_flags, axis=1), np.count_nonzero(valid_flags, axis=1)
        found = flag_patterns(inside_flags, valid_flags)
    else:
        n_in, n_valid, keys = scan.inside_counts(priors, s.confidence, keys=patterns)
        found = key_patterns(*keys, len(priors)) if patterns else None
    err, semi = _statistics(scan, priors, s) if statistics else (None, None)
    return _curve_arrays(priors, n_in, n_valid, err, semi, s), found


def _statistics(scan: PriorScan, priors, s: CellSettings):
    """Each star's actual position error and its ellipse's semi-major axis at every prior
    (true position offsets are zero at the reference epoch, so the solved position is the
    actual error, Sect. 3.2)."""
    return scan.position_statistics(priors, s.confidence)


def _curve_arrays(priors, n_in, n_valid, err, semi_major, s: CellSettings) -> dict:
    n_in = np.asarray(n_in, dtype=np.int64)
    n_valid = np.asarray(n_valid, dtype=np.int64)
    if err is None or err.shape[1] == 0:
        p_err = med = np.full(len(priors), np.nan)
    else:
        valid = np.isfinite(err) & np.isfinite(semi_major)
        # A prior always gives a solution; the NaN-aware reductions (10x slower) only if not.
        pct, median = (np.percentile, np.median) if valid.all() else (np.nanpercentile, np.nanmedian)
        p_err = pct(err, 100.0 * s.confidence, axis=1)
        med = median(semi_major, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(n_valid > 0, n_in / np.maximum(n_valid, 1), np.nan)
    return {
        "sigma_prior_mas": np.asarray(priors, float),
        "fraction_inside": frac,
        "p_error_mas": p_err,
        "median_semi_major_mas": med,
        "n_inside": n_in,
        "n_valid": n_valid,
    }


def _curve_table(priors, n_in, n_valid, err, semi_major, s: CellSettings) -> pd.DataFrame:
    return pd.DataFrame(_curve_arrays(priors, n_in, n_valid, err, semi_major, s))


def prior_curve(n0, b0, priors_mas, s: CellSettings, *, method: str = "scan", return_inside: bool = False,
                statistics: bool = True):
    """Fraction inside, P-th percentile error and median semi-major axis per prior.

    ``method="scan"`` (default) reduces each star's normal equations once and evaluates
    every prior in a few dozen operations per star (:mod:`mcsweep.astrometry.prior_scan`,
    :func:`scan_curve`); ``"direct"`` solves the 5 x 5 system of every star and prior
    (the reference, kept for tests and ``benchmarks/bench_cell.py``). The fraction
    inside follows the NaN rule of :func:`mcsweep.astrometry.confidence.inside_counts`.
    ``statistics=False`` leaves the percentile and semi-major columns NaN (scan only).
    With ``return_inside`` also returns the per-star ``inside`` and ``valid`` flags,
    both (n_priors, n_stars) (for the bootstrap of :func:`sigma_f90_interval`).
    """
    priors = np.asarray(priors_mas, float)
    if method == "scan":
        table, inside_flags, valid_flags = scan_curve(prior_scan(n0, b0, s.ratio_R), priors, s,
                                                      statistics=statistics)
        return (table, inside_flags, valid_flags) if return_inside else table
    if method != "direct":
        raise ValueError(f"method={method!r}; expected 'scan' or 'direct'")
    m, n = len(priors), n0.shape[0]
    counts = np.zeros((m, 2), dtype=np.int64)
    err = np.empty((m, n))
    semi_major = np.empty((m, n))
    inside_flags = np.zeros((m, n), dtype=bool)
    valid_flags = np.zeros((m, n), dtype=bool)
    for i, p in enumerate(priors):
        sol = solve_with_prior(n0, b0, p, ratio_R=s.ratio_R)
        dpos, cov2 = np.ascontiguousarray(sol.x[:, :2]), np.ascontiguousarray(sol.cov[:, :2, :2])
        counts[i] = inside_counts(dpos, cov2, s.confidence)
        err[i] = np.hypot(dpos[:, 0], dpos[:, 1])
        semi_major[i] = ellipse_semi_axes(cov2, s.confidence)[0]
        valid_flags[i] = np.isfinite(mahalanobis_sq(dpos, cov2))
        inside_flags[i] = inside(dpos, cov2, s.confidence) & valid_flags[i]
    table = _curve_table(priors, counts[:, 0], counts[:, 1], err, semi_major, s)
    return (table, inside_flags, valid_flags) if return_inside else table


def run_cell(cell, transits: pd.DataFrame | dict, source, s: CellSettings,
             *, keep_scatter: bool = False, radius_deg: float | None = None,
             grid_statistics: bool | None = None, draws: dict | None = None, arrow: bool = False,
             ) -> tuple[pd.DataFrame | pa.Table, pd.DataFrame | None]:
    """Run one cell; returns its curve table and (optionally) per-star errors (Fig. 2).

    ``cell`` is a :class:`mcsweep.experiments.f90_sweep.cells.Cell`; ``transits`` the FoV transits of
    its direction (columns of :func:`mcsweep.scanning.find_transits`, or :func:`transit_columns` of
    them). ``radius_deg`` skips the beam widening when the caller has already computed it (:func:`cell_radius`).
    ``grid_statistics``: compute ``p_error_mas`` and ``median_semi_major_mas`` at every
    prior of the grid (True) or only at sigma_F90 (False; NaN on the grid rows); None
    follows ``s.grid_statistics``. The fraction inside is always on the whole grid.
    ``draws``: a dict shared by the colour cells of one direction x G bin run together, so
    they draw its batches once (:func:`cell_stars`); the results do not depend on it.
    ``arrow``: return the curve table as the Arrow table ``pa.Table.from_pandas`` makes of the
    DataFrame, built without one (what the sweep's workers write).
    """
    d = cell.direction
    # Streams keyed by content (cell, and case *name* for the noise), never by position in
    # a list, so adding, removing or reordering cases or cells changes no other result.
    radius = cell_radius(source, cell, s)[0] if radius_deg is None else radius_deg
    stars = cell_stars(cell, source, s, radius, _STAR_STREAM, draws)
    columns = transit_columns(transits)
    grid = np.asarray(s.prior_grid_mas, float)
    stats_on_grid = s.grid_statistics if grid_statistics is None else bool(grid_statistics)
    base = dict(cell_id=cell.cell_id, l_deg=d.l_deg, b_deg=d.b_deg, ra_deg=d.ra_deg,
                dec_deg=d.dec_deg, g_min=cell.g_min, g_max=cell.g_max, n_stars=len(stars),
                n_in_cone=int(stars.attrs.get("n_in_cone", len(stars))), radius_deg=radius,
                n_groups=len(np.unique(columns["group"])))
    if s.colour_axis:
        base.update(bp_rp_min=np.nan if cell.bp_rp_min is None else cell.bp_rp_min,
                    bp_rp_max=np.nan if cell.bp_rp_max is None else cell.bp_rp_max)
    centre = None
    if s.mean:
        centre = cell_mean(cell_stars(cell, source, s, radius, _MEAN_STREAM, draws), d)
        base.update(centre)
    solved = stars if centre is None else _shifted(stars, centre)
    normals = _case_normals(cell, columns, solved, s) if len(stars) >= _min_stars(cell) else {}
    scans = {case: nrm.prior_scan(s.ratio_R) for case, nrm in normals.items()}
    curves, f90_patterns = {}, None
    for case, scan in scans.items():
        curves[case], patterns = scan_arrays(scan, grid, s, statistics=stats_on_grid, patterns=case == s.f90_case)
        if case == s.f90_case:
            f90_patterns = patterns
    f90 = _cell_f90(cell, grid, curves, f90_patterns, s, has_stars=len(stars) > 0,
                    enough_stars=len(stars) >= _min_stars(cell))
    if centre is not None:
        base.update(_quasars(cell, columns, stars, centre, f90["sigma_f90_mas"], s))
    columns = _cell_columns(grid, curves, scans, s, dict(base, **f90))
    table = table_from_columns(columns) if arrow else pd.DataFrame(columns)
    scatter = None
    if keep_scatter and s.f90_case in normals:
        scatter = _scatter(normals[s.f90_case], stars, f90["sigma_f90_mas"], s)
    return table, scatter


def _min_stars(cell) -> int:
    return COLOUR_MIN_STARS if cell.has_colour else 1


def cell_stars(cell, source, s: CellSettings, radius: float, stream: int,
               draws: dict | None = None) -> pd.DataFrame:
    """The stars of a cell from stream ``stream`` of its key.

    A colour-blind cell is one draw of the beam and G bin (at least ``min_stars`` from a
    density, :func:`cell_radius`). A colour cell takes the stars of its BP-RP bin from the
    batches of its direction x G bin (:class:`ColourBatches`, at most
    :data:`COLOUR_DRAW_BATCHES`; a catalogue has one) until it holds ``min_stars``, capped at
    ``max_stars``. ``attrs["n_in_cone"]`` is then the first batch's one-realisation count
    scaled by the share of the bin in it. ``draws``: batches already drawn, shared by the
    colour cells of one direction x G bin (filled here; the stars do not depend on it).
    """
    if not cell.has_colour:
        rng = np.random.default_rng(np.random.SeedSequence(s.seed, spawn_key=(*cell.key, stream)))
        return _draw_cone(cell, source, s, radius, rng, colours=False)
    slot = (cell.key[:4], stream, radius)
    batches = draws.get(slot) if draws is not None else None
    if batches is None:
        batches = ColourBatches(cell, source, s, radius, stream)
        if draws is not None:
            draws[slot] = batches
    kept, n_kept, n_in_cone = [], 0, None
    for i in range(COLOUR_DRAW_BATCHES if getattr(source, "draws_from_density", False) else 1):
        batch = batches.batch(i)
        in_bin = np.flatnonzero((batch.bp_rp >= cell.bp_rp_min) & (batch.bp_rp < cell.bp_rp_max))
        if n_in_cone is None:
            n_in_cone = int(round(batch.n_in_cone * in_bin.size / max(len(batch), 1)))
        # only the rows kept are made: beyond max_stars they would be cut off below
        kept.append((batch, in_bin[:max(s.max_stars - n_kept, 0)]))
        n_kept += in_bin.size
        if n_kept >= s.min_stars or len(batch) == 0:
            break
    # the batches' rows in one table (a galaxy model's draws: made in one pass)
    out = type(kept[0][0]).stars_of(kept).iloc[:s.max_stars]
    out.attrs["n_in_cone"] = n_in_cone
    return out


def _draw_cone(cell, source, s: CellSettings, radius: float, rng: np.random.Generator, *,
               colours: bool = True) -> pd.DataFrame:
    """The stars of a cell's beam and G bin; without ``colours`` from a source that can skip
    them, their BP-RP may be NaN (a colour-blind cell never reads it)."""
    d = cell.direction
    more = {"min_draw": s.min_stars} if getattr(source, "draws_from_density", False) else {}
    if not colours and getattr(source, "colours_optional", False):
        more["colours"] = False
    return source.sample_cone(d.l_deg, d.b_deg, radius, cell.g_min, cell.g_max, rng, max_stars=s.max_stars, **more)


class ColourBatches:
    """The batches of stars of one direction x G bin from which its colour cells take theirs.

    Batch ``i`` is one draw of the beam and G bin (as a colour-blind cell draws) from its own
    generator, ``SeedSequence(seed, spawn_key=(*direction_g_key, stream, COLOUR_BATCH_STREAM, i))``:
    keyed by content, so every colour cell of the direction x G bin sees the same batches
    whichever asks first, and a task that runs them together draws each batch once. The bins
    are disjoint, so the cells' stars are disjoint subsets of one draw: independent
    realisations of the density restricted to each bin (thinning of a Poisson process).

    A batch is drawn as far as its stars' colours (:meth:`GalaxyModel.draw_cone
    <mcsweep.population.GalaxyModel.draw_cone>`); each cell makes the rows of its own bin only
    (most of a late batch's stars belong to bins that already have theirs), the values those
    of the whole draw's table bit for bit. A catalogue's one batch is its table.
    """

    def __init__(self, cell, source, s: CellSettings, radius: float, stream: int):
        self._args = (cell, source, s, radius)
        self._key = (*cell.key[:4], stream, COLOUR_BATCH_STREAM)
        self._drawn: dict = {}

    def batch(self, i: int):
        """Batch ``i``: ``bp_rp`` (array), ``n_in_cone``, ``len``, ``stars(rows)`` and
        ``stars_of(parts)`` (the rows of several batches in one table)."""
        if i not in self._drawn:
            cell, source, s, radius = self._args
            rng = np.random.default_rng(np.random.SeedSequence(s.seed, spawn_key=(*self._key, i)))
            if getattr(source, "draws_from_density", False) and hasattr(source, "draw_cone"):
                d = cell.direction
                self._drawn[i] = source.draw_cone(d.l_deg, d.b_deg, radius, cell.g_min, cell.g_max, rng,
                                                  max_stars=s.max_stars, min_draw=s.min_stars)
            else:
                self._drawn[i] = _TableBatch(_draw_cone(cell, source, s, radius, rng))
        return self._drawn[i]


class _TableBatch:
    """A drawn table with the interface of a :class:`~mcsweep.population.galaxy.model.ConeDraw`
    (``bp_rp``, ``n_in_cone``, ``len``, ``stars`` and ``stars_of``)."""

    def __init__(self, table: pd.DataFrame):
        self._table = table
        self.bp_rp = table["bp_rp"].to_numpy(float)
        self.n_in_cone = table.attrs.get("n_in_cone", len(table))

    def __len__(self) -> int:
        return len(self._table)

    def stars(self, index) -> pd.DataFrame:
        return self._table.iloc[np.asarray(index, dtype=np.intp)]

    @staticmethod
    def stars_of(parts) -> pd.DataFrame:
        return pd.concat([batch.stars(index) for batch, index in parts], ignore_index=True)


def cell_mean(stars: pd.DataFrame, d) -> dict:
    """The mean parallax and proper motion of a cell's stars: the centre of a mean-centred
    prior. The proper motion is averaged in galactic components (each star's own rotation)
    and given in ICRS at the beam centre too, the frame the cell's solutions use."""
    if len(stars) == 0:
        nan = float("nan")
        return dict(mean_parallax_mas=nan, mean_pml_masyr=nan, mean_pmb_masyr=nan, mean_pmra_masyr=nan,
                    mean_pmdec_masyr=nan, n_mean_stars=0)
    pml, pmb = pm_galactic_from_icrs(*(stars[c].to_numpy(float) for c in ("ra", "dec", "pmra", "pmdec")))
    m_l, m_b = float(np.mean(pml)), float(np.mean(pmb))
    m_ra, m_dec = pm_icrs_from_galactic(d.l_deg, d.b_deg, m_l, m_b)
    return dict(mean_parallax_mas=float(stars["parallax"].mean()), mean_pml_masyr=m_l, mean_pmb_masyr=m_b,
                mean_pmra_masyr=float(m_ra), mean_pmdec_masyr=float(m_dec), n_mean_stars=len(stars))


def _shifted(stars: pd.DataFrame, centre: dict) -> pd.DataFrame:
    """The stars with the prior's centre subtracted from their truth. A prior centred on m
    gives the same errors as a zero-centred one with the truth x - m (the estimate is linear:
    x_hat - x = (N + N_p)^-1 (n + N_p (m - x)), Eqs. 11-13), so every cell solves with the
    zero-centred Eq. 18."""
    return stars[["phot_g_mean_mag"]].assign(
        parallax=stars["parallax"].to_numpy(float) - centre["mean_parallax_mas"],
        pmra=stars["pmra"].to_numpy(float) - centre["mean_pmra_masyr"],
        pmdec=stars["pmdec"].to_numpy(float) - centre["mean_pmdec_masyr"])


def _quasars(cell, columns: dict, stars: pd.DataFrame, centre: dict, f90: float, s: CellSettings) -> dict:
    """Sources with zero parallax and proper motion (quasars) at the cell's stars' G, solved in
    the F90 case with the mean-centred prior of width sigma_F90: fraction inside the P ellipse
    and P-th percentile position error. Their truth relative to the prior's centre is -m."""
    out = dict(quasar_fraction_inside=np.nan, quasar_n_valid=0, quasar_p_error_mas=np.nan)
    geom = case_geometry(columns, tuple(s.cases[s.f90_case])) if len(columns["group"]) else None
    if geom is None or not math.isfinite(f90) or len(stars) == 0:
        return out
    zero = {"parallax": 0.0, "pmra": 0.0, "pmdec": 0.0}
    quasars = _shifted(stars.assign(**zero), centre)
    rng = np.random.default_rng(np.random.SeedSequence(s.seed, spawn_key=(*cell.key, _QUASAR_STREAM)))
    normals = cell_normals(geom, cell.direction.ra_deg, cell.direction.dec_deg, quasars, s, rng)
    row = scan_arrays(normals.prior_scan(s.ratio_R), [f90], s, statistics=True)[0]
    return dict(quasar_fraction_inside=float(row["fraction_inside"][0]), quasar_n_valid=int(row["n_valid"][0]),
                quasar_p_error_mas=float(row["p_error_mas"][0]))


def _case_normals(cell, columns: dict, stars: pd.DataFrame, s: CellSettings) -> dict:
    """The normal equations of every observation case with transits (and stars), by case;
    ``columns``: the direction's transits as :func:`transit_columns` gives them."""
    normals = {}
    weights_and_truth = _weights_and_truth(stars, s) if len(stars) else None
    for case, groups in s.cases.items():
        geom = case_geometry(columns, tuple(groups))
        if geom is not None and len(stars) > 0:
            case_ss = np.random.SeedSequence(s.seed, spawn_key=(*cell.key, _NOISE_STREAM,
                                                                zlib.crc32(case.encode())))
            normals[case] = cell_normals(geom, cell.direction.ra_deg, cell.direction.dec_deg, stars, s,
                                         np.random.default_rng(case_ss), weights_and_truth=weights_and_truth)
    return normals


def _cell_f90(cell, grid, curves: dict, f90_patterns, s: CellSettings, *, has_stars: bool,
              enough_stars: bool = True) -> dict:
    """sigma_F90 of the cell from the F90 case's curve (Sect. 3.3), its flag, its bootstrap
    interval (over the stars' ``f90_patterns`` of flags) and whether it is ill-determined."""
    if s.f90_case not in curves:
        flag = "no_stars" if not has_stars else "few_stars" if not enough_stars else "no_transits"
        return dict(sigma_f90_mas=float("nan"), f90_flag=flag,
                    sigma_f90_lo_mas=float("nan"), sigma_f90_hi_mas=float("nan"), ill_determined=False)
    c = curves[s.f90_case]
    f90, flag = sigma_f90_from_curve(grid, c["fraction_inside"], s.confidence, s.interpolation)
    boot_rng = np.random.default_rng(np.random.SeedSequence(s.seed, spawn_key=(*cell.key, _BOOTSTRAP_STREAM)))
    lo, hi = pattern_interval(grid, f90_patterns, s.confidence, s.interpolation, s.n_bootstrap, boot_rng)
    return dict(sigma_f90_mas=f90, f90_flag=flag, sigma_f90_lo_mas=lo, sigma_f90_hi_mas=hi,
                ill_determined=ill_determined(grid, c["fraction_inside"], c["n_valid"], s.confidence))


def _cell_columns(grid, curves: dict, scans: dict, s: CellSettings, scalars: dict) -> dict:
    """The cell's rows (:data:`CURVE_COLUMNS`) as numpy columns: every case on the grid, then
    at sigma_F90."""
    f90 = scalars["sigma_f90_mas"]
    empty = _curve_arrays(grid, np.zeros(len(grid)), np.zeros(len(grid)), None, None, s)
    empty["fraction_inside"] = np.full(len(grid), np.nan)
    parts, at_f90, case_col = [], [], []

    def add(part, case, at):
        parts.append(part)
        at_f90.append(np.full(len(part["sigma_prior_mas"]), at))
        case_col.extend([case] * len(part["sigma_prior_mas"]))

    for case in s.cases:
        if case in curves:
            add(curves[case], case, False)
            if math.isfinite(f90):
                add(scan_arrays(scans[case], [f90], s, statistics=True)[0], case, True)
        else:
            add(empty, case, False)
    cols = {k: np.concatenate([p[k] for p in parts]) for k in empty}
    n_rows = len(cols["sigma_prior_mas"])
    cols["at_f90"] = np.concatenate(at_f90)
    cols["case"] = np.array(case_col, dtype=object)
    for k, v in scalars.items():
        cols[k] = np.full(n_rows, v, dtype=object if isinstance(v, str) else None)
    return {k: cols[k] for k in curve_columns(s)}


def _scatter(normals, stars: pd.DataFrame, f90: float, s: CellSettings) -> pd.DataFrame:
    """Per-star position errors and covariances of the F90 case at the scatter priors and at
    sigma_F90 (Fig. 2)."""
    priors = list(s.scatter_priors_mas) + ([f90] if math.isfinite(f90) else [])
    labels = [f"{p:g} mas" for p in s.scatter_priors_mas] + (["F90"] if math.isfinite(f90) else [])
    parts = []
    for label, sigma in zip(labels, priors):
        dpos, cov2 = _evaluate(normals, float(sigma), s)
        parts.append(pd.DataFrame({
            "prior": label, "sigma_prior_mas": float(sigma),
            "dra_mas": dpos[:, 0], "ddec_mas": dpos[:, 1],
            "cov_aa": cov2[:, 0, 0], "cov_ad": cov2[:, 0, 1], "cov_dd": cov2[:, 1, 1],
            "parallax": stars["parallax"].to_numpy(float)}))
    return pd.concat(parts, ignore_index=True).assign(case=s.f90_case)


#: ``MEAN_COLUMNS`` was renamed CELL_MEAN_COLUMNS (three modules had a MEAN_COLUMNS of different columns).
__getattr__ = old_names(__name__, {"MEAN_COLUMNS": "CELL_MEAN_COLUMNS"})
