"""The solver's blocks of the primary solution, built chunk by chunk (paper Sect. 4.2, steps 2-3).

A chunk is a run of consecutive solver blocks of ``SOLVER_BLOCK_STARS`` solved stars; one
function, :func:`build_chunk`, builds it from the partitions of the table it overlaps (their
rows, transit summaries and transits, :mod:`~.transits`), wherever it runs: in this process
(:class:`~.local.InProcess`) or on a Dask worker (:class:`~.cluster.OnCluster`). Each block's
measurements are truth plus the true attitude through the very partials the solver holds,
plus unit noise from the block's own seed (``stream_seed(seed, NOISE_STREAM, block)``), so
neither the chunking nor where a chunk is built changes a bit.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ...scanning.ephemeris import gaia_position_au
from ...solver import AttitudeSpline, build_measurements, in_block_order, make_blocks, source_normals
from ...solver.attitude_spline import DEGREE
from ...solver.blocks import att_band, att_rows, src_forward
from ...solver.calibration import basic_angle_columns
from ...solver.reduction import AlignedPartials, pairwise_sum
from ..global_solution.classes import STAR_COLUMNS
from .experiment import NOISE_STREAM, PrimarySettings, star_sigmas, stream_seed
from .transits import block_transits
from .truth import block_epochs, rotation_at, true_parameters

__all__ = ["BlockJob", "ChunkSpec", "build_block", "build_chunk", "covered_coefficients", "fold_infos",
           "solved_columns"]


@dataclasses.dataclass(frozen=True)
class ChunkSpec:
    """What one chunk's task needs besides its partitions: its blocks ``(k, first solved star,
    stars, first measurement)``, per partition it overlaps (in star order) ``(first star of the
    partition, first and end solved star within it)``, the stars per block, whether the
    measurements get noise and whether the chunk's attitude band is summed where it is built
    (to travel to the driver, :func:`fold_infos`)."""

    blocks: tuple
    parts: tuple
    block_stars: int
    with_noise: bool = True
    band: bool = True


def solved_columns(part: pd.DataFrame, summary: dict, first: int, lo: int, hi: int) -> dict:
    """The star columns of a partition's solved stars ``lo:hi`` (counted within it), their
    indices in the table (``star``; the partition starts at star ``first``) and mean live epochs."""
    idx = np.flatnonzero(summary["solved"])[lo:hi]
    out = {c: part[c].to_numpy()[idx] for c in STAR_COLUMNS}
    out["star"] = first + idx
    out["mean_tcb_jd"] = summary["mean_tcb_jd"][idx]
    return out


def joined(arrays: list) -> np.ndarray:
    """``arrays`` end to end; one array as it is (a single partition's transits are not copied)."""
    return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)


def chunk_transits(transits: list, stars: np.ndarray) -> dict:
    """The transits of the partitions (each sorted by star, in star order) of the stars
    ``stars[0] .. stars[-1]``, end to end (views where one partition holds them)."""
    out = {}
    for tr in transits:
        a, b = np.searchsorted(tr["star"], [stars[0], stars[-1] + 1])
        for key, values in tr.items():
            out.setdefault(key, []).append(values[a:b])
    return {key: joined(values) for key, values in out.items()}


def build_chunk(spec: ChunkSpec, settings: PrimarySettings, spline, true_attitude, dead, *inputs) -> tuple:
    """A solver chunk ``(blocks, measurements, kept)`` and what the driver needs of it: which
    spline coefficients its measurements touch, the blocks' rows and, with ``spec.band``, its
    blocks' attitude band summed in the fixed tree. ``inputs``: per partition of ``spec.parts``,
    its table, summary and transits. ``kept``: the stars' data normal matrices, truth, (l, b,
    G), table indices and mean live epochs, and with ``basic_angle_harmonics`` each block's
    calibration design (:func:`build_block`; its transits need their fields of view)."""
    cols = [solved_columns(p, s, *ps) for p, s, ps in zip(inputs[0::3], inputs[1::3], spec.parts)]
    solved = {c: joined([x[c] for x in cols]) for c in cols[0]}
    tr = chunk_transits(inputs[2::3], solved["star"])
    star, t, psi = tr["star"], tr["t"], tr["psi"]
    live = ~dead.is_dead(t)
    harmonics = settings.basic_angle_harmonics
    following = tr.get("following") if harmonics else None
    offset = spec.blocks[0][1]
    blocks, hs, normals, x_true, cals = [], [], [], [], []
    for k, first, n, first_row in spec.blocks:
        v = slice(first - offset, first - offset + n)
        xt = true_parameters(solved, v)
        sa, sc = star_sigmas(settings, solved, v)
        job = BlockJob(first=first, ra=solved["ra"][v], dec=solved["dec"][v], x_true=xt, sigma_al_mas=sa,
                       sigma_ac_mas=sc, first_row=first_row,
                       noise_seed=stream_seed(settings.seed, NOISE_STREAM, k) if spec.with_noise else None)
        blk, nrm, h, cal = build_block(job, *block_transits(star, t, psi, live, solved["star"][v], following),
                                       spline=spline, true_attitude=true_attitude, t_ref_jd=settings.t_ref_jd,
                                       block_stars=spec.block_stars, law=settings.law, harmonics=harmonics)
        blocks.append(blk)
        hs.append(h)
        normals.append(nrm)
        x_true.append(xt)
        cals.append(cal)
    kept = {"normals": np.concatenate(normals), "x_true": np.concatenate(x_true),
            **{c: solved[c] for c in ("star", "l", "b", "phot_g_mean_mag", "mean_tcb_jd")}}
    if harmonics:
        kept["calibration"] = cals
    info = {"band": pairwise_sum(att_band(b) for b in blocks) if spec.band else None,
            "covered": np.flatnonzero(covered_coefficients(blocks, spline.n_coef)),
            "rows": [(b.rows.start, b.rows.stop) for b in blocks]}
    return (blocks, hs, kept), info


def fold_infos(starts: list, levels: list, n_coef: int, *infos) -> tuple:
    """One worker's chunks' build results (:func:`build_chunk`) folded: their attitude bands
    added where the fixed tree adds them (:class:`~mcsweep.solver.reduction.AlignedPartials`),
    the coefficients they touch, and each chunk's blocks' rows."""
    fold = AlignedPartials()
    covered = np.zeros(n_coef, dtype=bool)
    for start, level, info in zip(starts, levels, infos):
        if info["band"] is not None:
            fold.push(start, level, info["band"])
        covered[info["covered"]] = True
    return fold.partials, np.flatnonzero(covered), [info["rows"] for info in infos]


def covered_coefficients(blocks, n_coef: int) -> np.ndarray:
    """Which spline coefficients (per axis) have a measurement in their support."""
    covered = np.zeros(n_coef, dtype=bool)
    for b in blocks:  # the runs of equal first coefficient: a few per knot and block
        covered[(b.seg_j0[:, None] + np.arange(DEGREE + 1)).ravel()] = True
    return covered


@dataclasses.dataclass(frozen=True, kw_only=True)
class BlockJob:
    """What one block of solved stars needs besides its transits and the shared spline and truth:
    its first star (in the solution), the stars' directions [deg], true parameters (n, 5),
    uncertainties [mas] (AC None: AL only), the seed of its noise (None: none) and its first
    measurement in the problem's observation order."""

    first: int
    ra: np.ndarray
    dec: np.ndarray
    x_true: np.ndarray
    sigma_al_mas: np.ndarray
    sigma_ac_mas: np.ndarray | None
    noise_seed: np.random.SeedSequence | None
    first_row: int


def build_block(job: BlockJob, star, t, psi, following=None, *, spline: AttitudeSpline, true_attitude: tuple,
                t_ref_jd: float, block_stars: int, law=None, harmonics: int = 0):
    """One solver block from its stars' live transits (``star`` within the block, TCB JD ``t``,
    scan angle ``psi`` [deg]): (StarBlock, data normal matrices (n, 5, 5), normalised
    measurements, calibration design). The last is None, or with ``harmonics > 0`` the
    block's part of a basic-angle variation of the scanning ``law``
    (:func:`~mcsweep.solver.calibration.basic_angle_columns`, from each transit's field of
    view ``following``), in the block's order.

    The same function wherever the block is built (:func:`build_chunk`, in this process or on
    a Dask worker), so the data are the same bits. The
    measurements are truth plus the true attitude (:mod:`~.experiment` notes, step 3) through the very
    partials the solver holds, plus unit noise from the block's own seed (the block's
    identity, so neither the chunking nor where it is built changes it) in the block's order
    (by time).
    """
    obs = build_measurements(job.ra, job.dec, star, t, psi, gaia_position_au(t), t_ref_jd=t_ref_jd,
                             sigma_al_mas=job.sigma_al_mas[star],
                             sigma_ac_mas=None if job.sigma_ac_mas is None else job.sigma_ac_mas[star],
                             spline=spline)
    # Observation order = block order: each block's measurements are then a contiguous
    # slice of h, read as a view by the solver (no index array, no per-solution copy).
    (blk,) = make_blocks(obs, job.ra, job.dec, block_stars=block_stars, first_star=job.first)
    cal = None
    if harmonics:
        # obs holds the AL measurements in transit order, then the AC ones (build_measurements),
        # which get weight zero (any transit index in range serves them)
        order = blk.rows
        transit = np.where(order < t.size, order, order - t.size)
        cal = basic_angle_columns(obs.tcb_jd[order], np.asarray(following)[transit],
                                  job.sigma_al_mas[star[transit]], obs.is_ac[order], law, harmonics)
    (blk,) = in_block_order([blk], job.first_row)
    normals = source_normals(obs)
    del obs
    rot = rotation_at(true_attitude, block_epochs(t_ref_jd, blk))  # (m, 3) [mas]
    h = src_forward(blk, job.x_true)
    for c, rows in enumerate(att_rows(blk)):
        h += rows * rot[:, c]
    if job.noise_seed is not None:
        h += np.random.default_rng(job.noise_seed).standard_normal(h.size)
    return blk, normals, h, cal
