"""The primary experiment built, kept and solved on the workers of a Dask cluster (issue 27).

With ``execution=dask`` the driver does not search the transits, build the solver's blocks,
hold the measurements or hold any per-star array of the solution: each of those is a task
on the cluster, and the solver's chunks (:mod:`mcsweep.solver.dask_resident`) are the
futures of the tasks that built them. The driver keeps the input table of the stars
(population draw, its columns), the attitude (spline, band, Schur factor, CG vectors), the
frame, and per star the outcome it writes (inside flag, position and parallax errors).

Steps (``prepare_on_cluster``), each a set of tasks whose results stay on the workers
unless said otherwise:

1. Transits of each chunk of ``transit_stars`` stars (:func:`~.primary.transits_of`'s
   search); back to the driver only each star's number of live transits, mean live epoch
   and time span (:func:`~.primary.transit_summary`) and, with ``knot_transits``, the
   solution's live epochs (the knots are placed by the data: 8 bytes per transit, once).
2. The driver picks the solved stars, the spline, the first measurement of each block.
3. Each solver chunk (aligned runs of leaves of blocks of ``BLOCK_STARS`` stars,
   :func:`~mcsweep.solver.cg.solver_chunks`) is built by one task from the transit
   results it overlaps (worker to worker), block by block with
   :func:`~.primary.build_block`, the function the driver uses without a cluster, and each
   block's noise from its own seed: the same bits as :func:`~.primary.prepare`. The chunk
   keeps its stars' data normal matrices and truth; back to the driver come its part of
   the attitude block's band (summed in the solver's fixed tree) and which coefficients
   it touches.

Per prior (``solve_on_cluster``): the prior sigma of each star is sent (8 bytes per star);
the inverses, frame weights, solution, the frame rotator's sums and each star's outcome are
made on the workers (:func:`~mcsweep.solver.cg.star_arrays`, :func:`~.primary.block_frame_sums`,
:func:`~.primary.block_outcome`: the functions of the local path, summed in the same tree,
so the same bits as a forked or in-process run).

A lost worker takes its chunks and the inputs scattered to it: its chunks are built again
from the driver's table of stars (transit search included) and the solution restarts from
its first pass (:class:`~mcsweep.solver.cg.ChunksLost`), with the same bits (tested by
killing a worker mid-solve).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ..astrometry.solve import prior_diagonal
from ..solver import BLOCK_STARS, solve_global
from ..solver.blocks import BlockSpan, att_band
from ..solver.cg import (MAX_RESTARTS, ChunksLost, ResidentProblem, chunk_values, penalty_weights, solver_chunks,
                         star_arrays, typical_weights, weight_sums)
from ..solver.frame import frame_from_sums
from ..solver.dask_resident import DaskChunks, _is_loss
from ..solver.reduction import pairwise_sum, run_level
from .global_classes import star_transits
from .primary import (NOISE_STREAM, BlockJob, PreparedData, PrimarySettings, _true_attitude, attitude_spline,
                      block_frame_sums, block_outcome, block_rows, block_transits, build_block,
                      covered_coefficients, dead_time_of, min_transits,
                      measurements_per_star, solved_stars, star_sigmas, stream_seed, transit_summary,
                      true_parameters, with_transit_columns)

__all__ = ["prepare_on_cluster", "solve_on_cluster"]


def _search(radec: tuple, first: int, start_jd: float, end_jd: float, law) -> dict:
    return star_transits(radec[0], radec[1], start_jd, end_jd, law, first=first)


def _summary(transits: dict, dead, first: int, n: int, knots_by_data: bool, min_fov: int) -> dict:
    """Per star of the chunk its live transits' count, mean epoch and span; with
    ``knots_by_data`` also the live epochs of the stars the solution will hold."""
    out = transit_summary(transits["star"], transits["t"], dead, first, n)
    live = out.pop("live")
    if knots_by_data:
        solvable = out["n_fov"] >= min_fov
        out["epochs"] = transits["t"][live & solvable[transits["star"] - first]]
    return out


def _build_chunk(spec: dict, spline, true_attitude, dead, *parts) -> tuple:
    """A solver chunk ``(blocks, measurements)`` and what the driver needs of it: its stars'
    data normal matrices, its blocks' attitude band summed in the fixed tree, and which spline
    coefficients its measurements touch. ``parts``: the transit results it overlaps, in star order."""
    star = np.concatenate([p["star"] for p in parts])
    t = np.concatenate([p["t"] for p in parts])
    psi = np.concatenate([p["psi"] for p in parts])
    live = ~dead.is_dead(t)
    blocks, hs, normals = [], [], []
    for job, solved_block in zip(spec["jobs"], spec["solved"]):
        blk, nrm, h, _ = build_block(job, *block_transits(star, t, psi, live, solved_block), spline=spline,
                                  true_attitude=true_attitude, t_ref_jd=spec["t_ref_jd"],
                                  block_stars=spec["block_stars"])
        blocks.append(blk)
        hs.append(h)
        normals.append(nrm)
    info = {"band": pairwise_sum(att_band(b) for b in blocks),
            "covered": np.flatnonzero(covered_coefficients(blocks, spline.n_coef)),
            "rows": [(b.rows.start, b.rows.stop) for b in blocks]}
    kept = {"normals": np.concatenate(normals), "x_true": np.concatenate([j.x_true for j in spec["jobs"]])}
    return (blocks, hs, kept), info


def _attach_prior(chunk: tuple, arg: tuple) -> tuple:
    """The solver's chunk ``(blocks, measurements, state)`` for one prior, made on its worker:
    the stars' arrays of that prior (:func:`~mcsweep.solver.cg.star_arrays`) in the state,
    from the prior sigma per star [mas] and R (``arg``), which is all that is sent per prior."""
    blocks, hs, kept = chunk
    sig, ratio_r = arg
    stars = star_arrays(blocks, kept["normals"], prior_diagonal(sig, ratio_r))
    stars.update(kept)
    first, binv = blocks[0].first, stars["binv"]
    return ([dataclasses.replace(b, binv=binv[b.first - first:b.first - first + b.n]) for b in blocks], hs,
            {"stars": stars})


def _slices(blocks) -> list:
    first = blocks[0].first
    return [slice(b.first - first, b.first - first + b.n) for b in blocks]


def _prior_task(item):
    """What the driver needs of a chunk's stars under a prior: singular blocks, the frame
    weights' sums (fixed tree) and the per-star weights whose medians set the frame penalty."""
    ci, blocks, _, st = item
    S = st["stars"]
    pos, pm = typical_weights(S["normals"], S["prior"])
    return ci, (int(np.count_nonzero(~S["ok"])), pairwise_sum(weight_sums(S["g_raw"][v]) for v in _slices(blocks)),
                pos, pm)


def _fit_task(item):
    ci, blocks, _, st, equal = item
    S = st["stars"]
    dx = st["x"] - S["x_true"]
    return ci, pairwise_sum(block_frame_sums(S["K"][v], S["binv"][v], dx[v], equal) for v in _slices(blocks))


def _outcome_task(item):
    ci, blocks, _, st, eps, omega, tau, confidence = item
    S = st["stars"]
    dx = st["x"] - S["x_true"]
    parts = [block_outcome(S["K"][v], S["binv"][v], dx[v], eps, omega, None if tau is None else tau[v], confidence)
             for v in _slices(blocks)]
    return ci, tuple(np.concatenate([p[i] for p in parts]) for i in range(3))


def solve_on_cluster(settings: PrimarySettings, data: PreparedData, sig, client, *, chunk_stars, log, tau,
                     equal: bool, attitude_start=None):
    """One prior's solution of data built on the cluster (:func:`prepare_on_cluster`), every
    per-star array on the workers: the prior sigmas ``sig`` [mas] of the solved stars are
    sent, the inverses, frame weights, solution and its evaluation are made there, and the
    driver gets the frame's sums, the attitude and per star only the outcome (inside flag,
    position and parallax errors; ``tau``: the epochs of ``evaluation_epoch='star_mean'``).
    A worker lost at any pass (the solution's or the evaluation's, whose stars' solution went
    with it) restarts the whole sequence on the rebuilt chunks: the same bits.
    Returns (solution, resident chunks, eps, omega, outcome, summed squared attitude error)."""
    spans = data.blocks
    if not spans:
        raise ValueError("no star with a transit to solve")
    ranges = solver_chunks(len(spans), spans[0].n, data.n_measurements, data.spline.n_coef, chunk_stars)
    views = [slice(spans[lo].first, spans[hi - 1].first + spans[hi - 1].n) for lo, hi in ranges]
    resident = data.resident(client, ranges).attached(_attach_prior, [(sig[v], settings.ratio_R) for v in views])
    for attempt in range(MAX_RESTARTS + 1):
        try:
            return (*_solve_once(settings, data, resident, ranges, views, chunk_stars=chunk_stars, log=log, tau=tau,
                                 equal=equal, attitude_start=attitude_start), )
        except ChunksLost:
            if attempt == MAX_RESTARTS:
                raise


def _solve_once(settings, data, resident, ranges, views, *, chunk_stars, log, tau, equal, attitude_start):
    levels = [run_level(lo, hi) for lo, hi in ranges]
    got = chunk_values(resident.run, _prior_task, [(ci,) for ci in range(len(ranges))])
    bad = sum(g[0] for g in got)
    if bad:
        raise ValueError(f"{bad} stars have singular source blocks; remove them first")
    n = data.solved.size
    w_pos, w_pm = penalty_weights(np.concatenate([g[2] for g in got]), np.concatenate([g[3] for g in got]), n)
    problem = ResidentProblem(data.blocks, n_coef=data.spline.n_coef, n_measurements=data.n_measurements,
                              naa_band=data.naa_band, frame_means=pairwise_sum((g[1] for g in got), None, levels) / n,
                              w_pos=w_pos, w_pm=w_pm)
    del got
    sol = solve_global(problem, None, **settings.criterion, log=log, chunk_stars=chunk_stars, residuals=False,
                       resident_chunks=resident, attitude_start=attitude_start)
    eps, omega = frame_from_sums(pairwise_sum(
        chunk_values(resident.run, _fit_task, [(ci, equal) for ci in range(len(ranges))]), None, levels))
    out = chunk_values(resident.run, _outcome_task, [(ci, eps, omega, None if tau is None else tau[v],
                                                    settings.confidence) for ci, v in enumerate(views)])
    outcome = tuple(np.concatenate([o[i] for o in out]) for i in range(3))
    sq = data.attitude_sq(sol.attitude, eps, omega, resident, ranges)
    return sol, resident, eps, omega, outcome, sq


def _first(pair):
    return pair[0]


def _second(pair):
    return pair[1]


class _Shared:
    """Objects every task may need (dead time, scanning law, spline, true attitude), scattered
    once, and again if a lost worker took them (the scheduler keeps one copy of scattered
    data: its memory manager drops the replicas of a broadcast)."""

    def __init__(self, client):
        self.client = client
        self.futures: dict = {}

    def __call__(self, name: str, obj):
        fut = self.futures.get(name)
        if fut is None or fut.status != "finished":
            (fut,) = self.client.scatter([obj], hash=False)
            self.futures[name] = fut
        return fut


def prepare_on_cluster(settings: PrimarySettings, stars: pd.DataFrame, client, *, chunk_stars: int | None,
                       transit_stars: int = 50000, block_stars: int = BLOCK_STARS,
                       with_noise: bool = True) -> PreparedData:
    """:func:`~.primary.prepare` with the transits, blocks and measurements made and kept on the
    workers of the Dask ``client`` (module notes): the same data, bit for bit, whose
    ``resident(client, ranges)`` for the solver's chunks of ``chunk_stars`` stars are the
    chunks already there. ``transit_stars``: stars per transit-search task. A worker lost
    while they are made (its scattered inputs with it) makes them again from the start."""
    for attempt in range(MAX_RESTARTS + 1):
        try:
            return _prepare_once(settings, stars, client, chunk_stars=chunk_stars, transit_stars=transit_stars,
                                 block_stars=block_stars, with_noise=with_noise)
        except Exception as exc:  # noqa: BLE001 - only a loss is repeated
            if attempt == MAX_RESTARTS or not _is_loss(exc):
                raise


def _prepare_once(settings, stars, client, *, chunk_stars, transit_stars, block_stars, with_noise) -> PreparedData:
    n = len(stars)
    dead = dead_time_of(settings)
    ra_all, dec_all = stars["ra"].to_numpy(), stars["dec"].to_numpy()
    shared = _Shared(client)

    def search(i: int):
        """The transit search of stars ``[i, i + 1) x transit_stars``, on one worker."""
        lo, hi = i * transit_stars, min((i + 1) * transit_stars, n)
        live_workers = sorted(client.scheduler_info()["workers"])
        (radec,) = client.scatter([(ra_all[lo:hi], dec_all[lo:hi])], workers=[live_workers[i % len(live_workers)]],
                                  hash=False)
        return client.submit(_search, radec, lo, settings.start_jd, settings.end_jd, shared("law", settings.law),
                             pure=False)

    found = [search(i) for i in range(-(-n // transit_stars))]
    summaries = [client.submit(_summary, f, shared("dead", dead), i * transit_stars, min(transit_stars, n - i * transit_stars),
                               settings.knot_transits is not None, min_transits(settings), pure=False)
                 for i, f in enumerate(found)]
    got = client.gather(summaries)
    del summaries
    summary = {k: np.concatenate([g[k] for g in got]) if got else np.zeros(0) for k in ("n_fov", "n_scheduled", "mean_t", "span")}
    summary["n_fov"] = summary["n_fov"].astype(np.int64)
    summary["n_scheduled"] = summary["n_scheduled"].astype(np.int64)
    stars = with_transit_columns(settings, stars, summary)
    solved = solved_stars(settings, summary["n_fov"])
    epochs = np.concatenate([g["epochs"] for g in got]) if settings.knot_transits is not None else None
    del got
    s_ac = star_sigmas(settings, stars, solved)[1]
    spline = attitude_spline(settings, dead, epochs)
    del epochs
    true_att = _true_attitude(settings)
    counts = measurements_per_star(summary["n_fov"][solved], s_ac)
    rows = block_rows(counts, block_stars)
    n_blocks = len(rows)
    ranges = solver_chunks(n_blocks, block_stars, int(counts.sum()), spline.n_coef, chunk_stars)

    def submit(ci: int, parts: list | None = None):
        """The task building chunk ``ci`` (from the transit results ``parts``; None: searched
        again, for a chunk lost with a worker: its scattered inputs went with it)."""
        blo, bhi = ranges[ci]
        live_workers = sorted(client.scheduler_info()["workers"])
        jobs, solved_blocks = [], []
        for k in range(blo, bhi):
            # the block's stars from the driver's table, element by element as prepare() has them
            first, last = k * block_stars, min((k + 1) * block_stars, solved.size)
            idx = solved[first:last]
            sa, sc = star_sigmas(settings, stars, idx)
            jobs.append(BlockJob(first=first, ra=ra_all[idx], dec=dec_all[idx], x_true=true_parameters(stars, idx),
                                 sigma_al_mas=sa, sigma_ac_mas=sc,
                                 noise_seed=stream_seed(settings.seed, NOISE_STREAM, k) if with_noise else None,
                                 first_row=int(rows[k])))
            solved_blocks.append(idx)
        star_lo, star_hi = solved[blo * block_stars], solved[min(bhi * block_stars, solved.size) - 1]
        span = range(star_lo // transit_stars, star_hi // transit_stars + 1)
        parts = [search(i) for i in span] if parts is None else parts[span.start:span.stop]
        home = [live_workers[ci % len(live_workers)]]
        (spec,) = client.scatter([{"jobs": jobs, "solved": solved_blocks, "t_ref_jd": settings.t_ref_jd,
                                   "block_stars": block_stars}], workers=home, hash=False)
        # spread over the workers as the scattered chunks are (memory), not where the transits are
        return client.submit(_build_chunk, spec, shared("spline", spline), shared("truth", true_att),
                             shared("dead", dead), *parts, pure=False,
                             workers=home, allow_other_workers=True)

    def rebuild(ci: int):
        return client.submit(_first, submit(ci), pure=False)

    built = [submit(ci, found) for ci in range(len(ranges))]
    chunk_futures = [client.submit(_first, b, pure=False) for b in built]
    infos = client.gather([client.submit(_second, b, pure=False) for b in built])
    del built, found  # a lost chunk is built again from the table of stars (rebuild)
    levels = [run_level(lo, hi) for lo, hi in ranges]
    naa_band = pairwise_sum((i["band"] for i in infos), None, levels)
    covered = np.zeros(spline.n_coef, dtype=bool)
    spans = []
    for (blo, bhi), info in zip(ranges, infos):
        covered[info["covered"]] = True
        for k, (r0, r1) in zip(range(blo, bhi), info["rows"]):
            spans.append(BlockSpan(first=k * block_stars, n=min(block_stars, solved.size - k * block_stars),
                                   rows=slice(r0, r1)))
    del infos  # the stars' truth and data normal matrices are with the chunks
    data = PreparedData(stars=stars, solved=solved, blocks=spans, normals=None, h=None, x_true=None,
                        spline=spline, true_attitude=true_att, t_ref_jd=settings.t_ref_jd, dead=dead,
                        covered=covered, n_rows=int(counts.sum()),
                        naa_band=np.zeros((0, 0)) if naa_band is None else naa_band)
    data.keep_resident(client, ranges, DaskChunks(client, chunk_futures, rebuild=rebuild))
    return data
