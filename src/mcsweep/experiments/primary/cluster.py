"""The primary experiment built, kept and solved on the workers of a Dask cluster.

With ``execution=dask`` the driver holds nothing per star: the table of stars
(:mod:`~.primary_sky`: partitions in sky order), the transits, the solver's blocks, the
measurements, every per-star array of a solution and each star's outcome are made and kept
on the cluster; the driver holds the attitude (spline, band, Schur factor, CG vectors), the
frame, a few numbers per partition, block and chunk, and one part of the per-star results
at a time while it writes them (:class:`~.primary_results.StarParts`). The solver's chunks
(:mod:`mcsweep.solver.dask_resident`) are the futures of the tasks that built them.

Steps (``prepare_on_cluster``), each a set of tasks whose results stay on the workers
unless said otherwise:

1. Per partition of the table: its transits, and per star the live transits' count, mean
   live epoch and span (:func:`~.primary.transit_summary`); back to the driver only the
   partition's number of solved stars and their live FoV transits, and with
   ``knot_transits`` the solution's live epochs (the knots are placed by the data: 8 bytes
   per transit, while the spline is made).
2. Per partition, given its first solved star: its stars' measurements summed by solver
   block (a few numbers per block), from which the driver has each block's first
   measurement.
3. Each solver chunk (aligned runs of leaves of blocks of ``SOLVER_BLOCK_STARS`` solved stars,
   :func:`~mcsweep.solver.problem.solver_chunks`) is built by one task from the partitions, their
   summaries and transits it overlaps (worker to worker), block by block with
   :func:`~.primary.build_block`, the function the driver uses without a cluster, and each
   block's noise from its own seed: the same bits as :func:`~.primary.prepare` of the whole
   table in the same order. The chunk keeps its stars' data normal matrices, truth, (l, b, G)
   and mean epochs; back to the driver come its part of the attitude block's band (summed in
   the solver's fixed tree) and which coefficients it touches. The transits are let go.

Per prior (``solve_on_cluster``): the prior's label is sent; the prior sigma of each star,
the inverses, frame weights, solution, the frame rotator's sums and each star's outcome are
made on the workers (:func:`~mcsweep.solver.problem.star_arrays`, :func:`~.primary.block_frame_sums`,
:func:`~.primary.block_outcome`: the functions of the local path, summed in the same tree, so
the same bits as a forked or in-process run). The per-star results come to the driver one
part (:data:`~.primary_results.PART_STARS` stars) at a time (:class:`~.primary_results.StarParts`).

A lost worker takes its chunks and the state of a solution: its chunks are built again from
the partitions (transit search included; a lost partition is made again by the scheduler
from its lineage, :mod:`~.primary_sky`) and the solution restarts from its first pass
(:class:`~mcsweep.solver.executors.ChunksLost`), with the same bits (tested by killing a worker
mid-solve); a loss while the parts are written solves the prior again (same bits).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Callable

import numpy as np
import pandas as pd

from ...astrometry.solve import prior_diagonal
from ...solver import SOLVER_BLOCK_STARS, solve_global
from ...solver.blocks import BlockSpan, att_band
from ...solver.dask_resident import DaskChunks, is_loss, live_workers
from ...solver.executors import MAX_RESTARTS, ChunksLost, chunk_values
from ...solver.frame import frame_from_sums, penalty_weights, typical_weights, weight_sums
from ...solver.problem import ResidentProblem, solver_chunks, star_arrays
from ...solver.reduction import AlignedPartials, pairwise_sum, run_level, share_of, sum_partials
from ...solver.selection import digit_counts, median
from ..global_solution.classes import STAR_COLUMNS, star_transits
from .experiment import (NOISE_STREAM, BlockJob, PreparedData, PrimarySettings, true_attitude, attitude_spline,
                      block_frame_sums, block_outcome, block_transits, build_block, covered_coefficients,
                      dead_time_of, epoch_offset_yr, first_rows, measurements_per_star, min_transits,
                      prior_sigmas, star_sigmas, stream_seed, transit_summary, true_parameters)
from .knots import ClusterEpochs, live_epochs
from .results import StarParts, solved_results
from .sky import SkyPartitions, alive

__all__ = ["prepare_on_cluster", "solve_on_cluster"]


def _retried(action: Callable, retry_if: Callable, between: Callable = lambda: None):
    """``action()``, repeated up to :data:`~mcsweep.solver.executors.MAX_RESTARTS` times when it
    raises an exception ``retry_if`` accepts (a loss), ``between()`` first; any other raised
    at once."""
    for attempt in range(MAX_RESTARTS + 1):
        try:
            return action()
        except Exception as exc:  # noqa: BLE001 - only what retry_if accepts is repeated
            if attempt == MAX_RESTARTS or not retry_if(exc):
                raise
            between()


def _is_chunks_lost(exc: BaseException) -> bool:
    return isinstance(exc, ChunksLost)


# --------------------------------------------------------------------------- tasks on the partitions
def _search(part: pd.DataFrame, first: int, start_jd: float, end_jd: float, law) -> dict:
    return star_transits(part["ra"].to_numpy(), part["dec"].to_numpy(), start_jd, end_jd, law, first=first)


def _summary(transits: dict, dead, first: int, n: int, min_fov: int) -> dict:
    """Per star of a partition: live FoV transits, scheduled ones, mean live epoch, span, and
    whether it is solved (at least ``min_fov`` live FoV transits)."""
    out = transit_summary(transits["star"], transits["t"], dead, first, n)
    out.pop("live")
    out["solved"] = out["n_fov"] >= min_fov
    return out


def _digest(summary: dict) -> dict:
    """What the driver needs of a partition: its solved stars and their live FoV transits."""
    solvable = summary["solved"]
    return {"n_solved": int(np.count_nonzero(solvable)), "n_fov": int(summary["n_fov"][solvable].sum())}


def _block_counts(summary: dict, part: pd.DataFrame, offset: int, block_stars: int, settings) -> tuple:
    """The measurements of a partition's solved stars (the first is solved star ``offset``)
    summed by solver block: (first block, sums)."""
    n_fov, solvable = summary["n_fov"], summary["solved"]
    counts = measurements_per_star(n_fov[solvable], star_sigmas(settings, part, solvable)[1])
    if not counts.size:
        return 0, np.zeros(0, dtype=np.int64)
    k = (offset + np.arange(counts.size)) // block_stars
    return int(k[0]), np.bincount(k - k[0], weights=counts).astype(np.int64)


def _solved_columns(part: pd.DataFrame, summary: dict, first: int) -> dict:
    idx = np.flatnonzero(summary["solved"])
    out = {c: part[c].to_numpy()[idx] for c in STAR_COLUMNS}
    out["star"] = first + idx
    out["mean_tcb_jd"] = summary["mean_tcb_jd"][idx]
    return out


def _build_chunk(spec: dict, settings: PrimarySettings, spline, true_attitude, dead, *inputs) -> tuple:
    """A solver chunk ``(blocks, measurements, kept)`` and what the driver needs of it: its
    blocks' attitude band summed in the fixed tree, which spline coefficients its measurements
    touch and the blocks' rows. ``inputs``: per partition it overlaps, in star order, its table,
    summary and transits."""
    parts, summaries, transits = inputs[0::3], inputs[1::3], inputs[2::3]
    cols = [_solved_columns(p, s, f) for p, s, f in zip(parts, summaries, spec["firsts"])]
    solved = {c: np.concatenate([x[c] for x in cols]) for c in cols[0]}
    star = np.concatenate([t["star"] for t in transits])
    t = np.concatenate([t["t"] for t in transits])
    psi = np.concatenate([t["psi"] for t in transits])
    live = ~dead.is_dead(t)
    blocks, hs, normals, x_true, rows = [], [], [], [], []
    for k, first, n, first_row in spec["blocks"]:
        v = slice(first - spec["offset"], first - spec["offset"] + n)
        xt = true_parameters(solved, v)
        sa, sc = star_sigmas(settings, solved, v)
        job = BlockJob(first=first, ra=solved["ra"][v], dec=solved["dec"][v], x_true=xt, sigma_al_mas=sa, sigma_ac_mas=sc,
                       noise_seed=stream_seed(settings.seed, NOISE_STREAM, k) if spec["with_noise"] else None,
                       first_row=first_row)
        blk, nrm, h, _ = build_block(job, *block_transits(star, t, psi, live, solved["star"][v]), spline=spline,
                                     true_attitude=true_attitude, t_ref_jd=settings.t_ref_jd,
                                     block_stars=spec["block_stars"])
        blocks.append(blk)
        hs.append(h)
        normals.append(nrm)
        x_true.append(xt)
        rows.append((blk.rows.start, blk.rows.stop))
    lo, hi = spec["blocks"][0][1] - spec["offset"], spec["blocks"][-1][1] + spec["blocks"][-1][2] - spec["offset"]
    kept = {"normals": np.concatenate(normals), "x_true": np.concatenate(x_true),
            **{c: solved[c][lo:hi] for c in ("star", "l", "b", "phot_g_mean_mag", "mean_tcb_jd")}}
    info = {"band": pairwise_sum(att_band(b) for b in blocks),
            "covered": np.flatnonzero(covered_coefficients(blocks, spline.n_coef)), "rows": rows}
    return (blocks, hs, kept), info


def _fold_infos(starts: list, levels: list, n_coef: int, *infos) -> tuple:
    """One worker's chunks' build results (:func:`_build_chunk`) folded: their attitude bands
    added where the fixed tree adds them (:class:`~mcsweep.solver.reduction.AlignedPartials`),
    the coefficients they touch, and each chunk's blocks' rows."""
    fold = AlignedPartials()
    covered = np.zeros(n_coef, dtype=bool)
    for start, level, info in zip(starts, levels, infos):
        fold.push(start, level, info["band"])
        covered[info["covered"]] = True
    return fold.partials, np.flatnonzero(covered), [info["rows"] for info in infos]


def _part_columns(part: pd.DataFrame, summary: dict, lo: int, hi: int) -> dict:
    """Rows ``lo:hi`` of a partition as the per-star results have them, and which are solved
    (with the number of solved stars before row ``lo``)."""
    solvable = summary["solved"]
    return {"class_key": part["class_key"].to_numpy()[lo:hi], "n_fov": summary["n_fov"][lo:hi],
            "n_fov_scheduled": summary["n_scheduled"][lo:hi], "span_days": summary["span_days"][lo:hi],
            "solved": solvable[lo:hi], "solved_before": int(np.count_nonzero(solvable[:lo]))}


# --------------------------------------------------------------------------- tasks on the solver's chunks
def _attach_prior(chunk: tuple, arg: tuple) -> tuple:
    """The solver's chunk ``(blocks, measurements, state)`` for one prior, made on its worker:
    each star's prior sigma from its (l, b, G) (``settings.sigma_f90_mas``, the prior
    ``label``) and the stars' arrays of that prior (:func:`~mcsweep.solver.problem.star_arrays`);
    ``arg = (settings, label)`` is all that is sent per prior."""
    blocks, hs, kept = chunk
    settings, label = arg
    sig = prior_sigmas(settings, label, kept["l"], kept["b"], kept["phot_g_mean_mag"])
    stars = star_arrays(blocks, kept["normals"], prior_diagonal(sig, settings.ratio_R))
    stars.update(kept)
    stars["sigma_prior"] = sig
    if settings.evaluation_epoch == "star_mean":
        stars["tau_yr"] = epoch_offset_yr(settings, kept["mean_tcb_jd"])
    first, binv = blocks[0].first, stars["binv"]
    return ([dataclasses.replace(b, binv=binv[b.first - first:b.first - first + b.n]) for b in blocks], hs,
            {"stars": stars})


def _slices(blocks) -> list:
    first = blocks[0].first
    return [slice(b.first - first, b.first - first + b.n) for b in blocks]


def _prior_task(item):
    """What the driver needs of a chunk's stars under a prior: singular blocks and the frame
    weights' sums (fixed tree)."""
    ci, blocks, _, st = item
    S = st["stars"]
    return ci, (int(np.count_nonzero(~S["ok"])), pairwise_sum(weight_sums(S["g_raw"][v]) for v in _slices(blocks)))


def _weight_digits(item):
    """A round of the selection of the medians that set the frame penalty
    (:mod:`mcsweep.solver.selection`): ``queries[w]`` for the stars' weights ``w`` (0 position,
    1 proper motion, :func:`~mcsweep.solver.frame.typical_weights`)."""
    ci, _, _, st, queries = item
    S = st["stars"]
    weights = typical_weights(S["normals"], S["prior"])
    return ci, [digit_counts(weights[w], [q])[0] for w, q in queries]


def _fit_task(item):
    ci, blocks, _, st, equal = item
    S = st["stars"]
    dx = st["x"] - S["x_true"]
    return ci, pairwise_sum(block_frame_sums(S["K"][v], S["binv"][v], dx[v], equal) for v in _slices(blocks))


def _outcome_task(item):
    """Each star's outcome, kept in the chunk's state for :func:`outcome_slice`."""
    ci, blocks, _, st, eps, omega, confidence = item
    S = st["stars"]
    dx = st["x"] - S["x_true"]
    tau_yr = S.get("tau_yr")
    parts = [block_outcome(S["K"][v], S["binv"][v], dx[v], eps, omega, None if tau_yr is None else tau_yr[v],
                           confidence)
             for v in _slices(blocks)]
    st["outcome"] = tuple(np.concatenate([p[i] for p in parts]) for i in range(3))
    return ci, None


def outcome_slice(item):
    """The outcome (inside, position and parallax errors) and prior sigma of the chunk's
    solved stars ``lo:hi`` (solved-star indices of the whole solution)."""
    ci, blocks, _, st, lo, hi = item
    first = blocks[0].first
    a, b = max(lo - first, 0), max(min(hi - first, len(st["stars"]["x_true"])), 0)
    return ci, (*(o[a:b] for o in st["outcome"]), st["stars"]["sigma_prior"][a:b])


# --------------------------------------------------------------------------- the driver's side
def _cluster_part(data: PreparedData, resident: DaskChunks, ranges, rows: slice) -> pd.DataFrame:
    """Part ``rows`` of a solution's per-star results, gathered from the partitions and chunks
    that hold its stars."""
    sky, info, client = data.sky, data.cluster, resident.client
    ends = sky.first + sky.sizes
    overlap = np.flatnonzero((sky.first < rows.stop) & (ends > rows.start))
    table = info["table"]

    def columns():
        table.ensure()
        return client.gather([client.submit(_part_columns, sky.futures[p], table.summaries[p],
                                            max(rows.start - sky.first[p], 0), min(rows.stop, ends[p]) - sky.first[p],
                                            pure=False) for p in overlap])

    got = _retried(columns, is_loss, lambda: time.sleep(1.0))  # (a moment for the scheduler's news of the loss)
    cols = {c: np.concatenate([g[c] for g in got]) for c in ("class_key", "n_fov", "n_fov_scheduled", "span_days",
                                                          "solved")}
    solved = cols.pop("solved")
    lo = int(info["solved_first"][overlap[0]] + got[0]["solved_before"]) if len(overlap) else 0
    hi = lo + int(np.count_nonzero(solved))
    outcome = ()
    if hi > lo:
        spans = data.blocks
        firsts = np.array([spans[a].first for a, _ in ranges])
        lasts = np.array([spans[b - 1].first + spans[b - 1].n for _, b in ranges])
        cis = np.flatnonzero((firsts < hi) & (lasts > lo))
        out = chunk_values(resident.run, outcome_slice, [(int(ci), lo, hi) for ci in cis])
        outcome = tuple(np.concatenate([o[i] for o in out]) for i in range(4))
    return solved_results(rows.start, cols["class_key"], cols["n_fov"], cols["n_fov_scheduled"], cols["span_days"],
                          solved, outcome)


def solve_on_cluster(settings: PrimarySettings, data: PreparedData, label: str, client, *, chunk_stars, log,
                     equal: bool, attitude_start=None):
    """One prior's solution of data built on the cluster (:func:`prepare_on_cluster`), every
    per-star array on the workers: the prior's ``label`` is sent, the prior sigmas, inverses,
    frame weights, solution and its evaluation are made there, and the driver gets the
    frame's sums, the attitude and the per-star results part by part
    (:class:`~.primary_results.StarParts`).
    A worker lost at any pass (the solution's or the evaluation's, whose stars' solution went
    with it) restarts the whole sequence on the rebuilt chunks: the same bits; lost while the
    parts are read, the prior is solved again.
    Returns (solution, resident chunks, eps, omega, StarParts, summed squared attitude error)."""
    spans = data.blocks
    if not spans:
        raise ValueError("no star with a transit to solve")
    ranges = solver_chunks(len(spans), spans[0].n, data.n_measurements, data.spline.n_coef, chunk_stars)

    def solve():
        resident = data.resident(client, ranges).attached(_attach_prior, [(settings, label)] * len(ranges))
        return (resident, *_retried(lambda: _solve_once(settings, data, resident, ranges, chunk_stars=chunk_stars,
                                                        log=log, equal=equal, attitude_start=attitude_start),
                                    _is_chunks_lost))

    state = {"solution": solve()}

    def resolve():  # the stars' outcome went with a worker: solved again, same bits
        state["solution"] = solve()

    def make(rows: slice) -> pd.DataFrame:
        return _retried(lambda: _cluster_part(data, state["solution"][0], ranges, rows), _is_chunks_lost, resolve)

    resident, sol, eps, omega, sq = state["solution"]
    return sol, resident, eps, omega, StarParts(data.n_stars, make), sq


def _solve_once(settings, data, resident, ranges, *, chunk_stars, log, equal, attitude_start):
    levels = [run_level(lo, hi) for lo, hi in ranges]
    got = chunk_values(resident.run, _prior_task, [(ci,) for ci in range(len(ranges))])
    bad = sum(g[0] for g in got)
    if bad:
        raise ValueError(f"{bad} stars have singular source blocks; remove them first")
    n = data.n_solved

    def counts_of(which: int):
        return lambda queries: chunk_values(resident.run, _weight_digits,
                                            [(ci, [(which, q) for q in queries]) for ci in range(len(ranges))])

    # the medians by selection, not by gathering every star's weights (mcsweep.solver.selection)
    w_pos, w_pm = penalty_weights(median(counts_of(0), n), median(counts_of(1), n), n)
    problem = ResidentProblem(data.blocks, n_coef=data.spline.n_coef, n_measurements=data.n_measurements,
                              naa_band=data.naa_band, frame_means=pairwise_sum((g[1] for g in got), None, levels) / n,
                              w_pos=w_pos, w_pm=w_pm)
    del got
    sol = solve_global(problem, None, **settings.criterion, log=log, chunk_stars=chunk_stars, residuals=False,
                       resident_chunks=resident, attitude_start=attitude_start)
    eps, omega = frame_from_sums(pairwise_sum(
        chunk_values(resident.run, _fit_task, [(ci, equal) for ci in range(len(ranges))]), None, levels))
    chunk_values(resident.run, _outcome_task, [(ci, eps, omega, settings.confidence) for ci in range(len(ranges))])
    sq = data.attitude_sq(sol.attitude, eps, omega, resident, ranges)
    return sol, eps, omega, sq


def _first(pair):
    return pair[0]


def _second(pair):
    return pair[1]


class _Table:
    """The table of stars on the cluster and each partition's per-star transit summary
    (:func:`_summary`), made again after a loss: the partitions from their classes
    (:meth:`~.primary_sky.SkyPartitions.ensure`), the summaries by searching the partitions'
    transits again (the tasks they came from are not kept by the scheduler)."""

    def __init__(self, sky: SkyPartitions, search: Callable, summarise: Callable):
        self.sky, self._search, self._summarise = sky, search, summarise
        self.found = [search(p) for p in range(len(sky))]
        self.summaries = [summarise(p, f) for p, f in enumerate(self.found)]

    def ensure(self) -> None:
        """Every partition and summary there (made again where a worker took them)."""
        remade = self.sky.ensure()
        for p, fut in enumerate(self.summaries):
            if remade or not alive(fut):
                self.summaries[p] = self._summarise(p, self._search(p))

    def transits(self, p: int):
        """A future of partition ``p``'s transits: the first search's while kept, else a new one."""
        if self.found is not None and alive(self.found[p]):
            return self.found[p]
        return self._search(p)

    def release_transits(self) -> None:
        self.found = None


class _Shared:
    """Objects every task may need (dead time, scanning law, settings, spline, true attitude),
    scattered once, and again if a lost worker took them (the scheduler keeps one copy of
    scattered data: its memory manager drops the replicas of a broadcast)."""

    def __init__(self, client):
        self.client = client
        self.futures: dict = {}

    def __call__(self, name: str, obj):
        fut = self.futures.get(name)
        if fut is None or fut.status != "finished":
            (fut,) = self.client.scatter([obj], hash=False)
            self.futures[name] = fut
        return fut


def prepare_on_cluster(settings: PrimarySettings, sky: SkyPartitions, client, *, chunk_stars: int | None,
                       block_stars: int = SOLVER_BLOCK_STARS, with_noise: bool = True) -> PreparedData:
    """:func:`~.primary.prepare` of the table ``sky`` (partitions on the workers of the Dask
    ``client``) with the transits, blocks and measurements made and kept there (module notes):
    the same data, bit for bit, as of the whole table in the same order, whose
    ``resident(client, ranges)`` for the solver's chunks of ``chunk_stars`` stars are the
    chunks already there. A worker lost while they are made makes them again from the start."""
    return _retried(lambda: _prepare_once(settings, sky, client, chunk_stars=chunk_stars, block_stars=block_stars,
                                          with_noise=with_noise), is_loss)


def _prepare_once(settings, sky, client, *, chunk_stars, block_stars, with_noise) -> PreparedData:
    from distributed import wait

    dead = dead_time_of(settings)
    shared = _Shared(client)
    min_fov = min_transits(settings)
    knots_by_data = settings.knot_transits is not None
    n_parts = len(sky)

    def search(p: int):
        return client.submit(_search, sky.futures[p], int(sky.first[p]), settings.start_jd, settings.end_jd,
                             shared("law", settings.law), pure=False)

    def summarise(p: int, transits):
        return client.submit(_summary, transits, shared("dead", dead), int(sky.first[p]), int(sky.sizes[p]),
                             min_fov, pure=False)

    table = _Table(sky, search, summarise)
    summaries, found = table.summaries, table.found
    digests = client.gather([client.submit(_digest, summaries[p], pure=False) for p in range(n_parts)])
    n_solved_p = np.array([d["n_solved"] for d in digests], dtype=np.int64)
    solved_first = first_rows(n_solved_p)
    n_solved = int(n_solved_p.sum())
    n_fov_transits = int(sum(d["n_fov"] for d in digests))
    del digests
    epochs = None
    if knots_by_data:  # placed by the epochs where they are (the knots come back, not the epochs)
        epochs = ClusterEpochs(client, [client.submit(live_epochs, summaries[p], found[p], shared("dead", dead),
                                                       int(sky.first[p]), pure=False)
                                         for p in range(n_parts)], settings.start_jd, settings.end_jd)
    spline = attitude_spline(settings, dead, epochs)
    del epochs
    true_att = true_attitude(settings)
    n_blocks = -(-n_solved // block_stars)
    per_block = np.zeros(n_blocks, dtype=np.int64)
    for k0, sums in client.gather([client.submit(_block_counts, summaries[p], sky.futures[p], int(solved_first[p]),
                                                 block_stars, shared("settings", settings), pure=False)
                                   for p in range(n_parts)]):
        per_block[k0:k0 + sums.size] += sums
    rows = first_rows(per_block)
    n_rows = int(per_block.sum())
    ranges = solver_chunks(n_blocks, block_stars, n_rows, spline.n_coef, chunk_stars)
    solved_end = solved_first + n_solved_p

    def submit(ci: int, workers=None):
        """The task building chunk ``ci`` (after a loss: from the partitions and summaries made
        again where the lost worker took them, the transits searched again; the live workers
        asked again unless given)."""
        table.ensure()
        blo, bhi = ranges[ci]
        lo, hi = blo * block_stars, min(bhi * block_stars, n_solved)
        ps = np.flatnonzero((solved_first < hi) & (solved_end > lo) & (n_solved_p > 0))
        spec = {"blocks": [(k, k * block_stars, min(block_stars, n_solved - k * block_stars), int(rows[k]))
                           for k in range(blo, bhi)],
                "offset": int(solved_first[ps[0]]), "firsts": [int(sky.first[p]) for p in ps],
                "block_stars": block_stars, "with_noise": with_noise}
        inputs = [x for p in ps for x in (sky.futures[p], table.summaries[p], table.transits(p))]
        workers = workers or live_workers(client)
        # spread over the workers (memory) in contiguous shares of the chunks, so each worker
        # sums its chunks' outputs before they travel (DaskChunks.reduced), not where the
        # transits are
        owner = share_of(ci, len(ranges), len(workers))
        return client.submit(_build_chunk, spec, shared("settings", settings), shared("spline", spline),
                             shared("truth", true_att), shared("dead", dead), *inputs, pure=False,
                             workers=[workers[owner]], allow_other_workers=True)

    def rebuild(ci: int):
        return client.submit(_first, submit(ci), pure=False)


    first = live_workers(client)  # one scheduler query for the first build
    built = [submit(ci, first) for ci in range(len(ranges))]
    chunk_futures = [client.submit(_first, b, pure=False) for b in built]
    infos = [client.submit(_second, b, pure=False) for b in built]
    del built, found
    levels = [run_level(lo, hi) for lo, hi in ranges]
    # each worker adds its chunks' bands where the fixed tree adds them: a few bands reach
    # the driver, not one per chunk (the same bits, reduction.AlignedPartials)
    wait(infos)
    holders = client.who_has(infos)
    groups: dict = {}
    for ci, f in enumerate(infos):
        groups.setdefault(min(holders.get(f.key) or [""]), []).append(ci)
    folded = client.gather([client.submit(_fold_infos, [ranges[ci][0] for ci in cis], [levels[ci] for ci in cis],
                                          spline.n_coef, *[infos[ci] for ci in cis], pure=False,
                                          workers=[w] if w else None, allow_other_workers=True)
                            for w, cis in groups.items()])
    del infos
    table.release_transits()  # a lost chunk searches its partitions again (rebuild)
    naa_band = sum_partials(f[0] for f in folded)
    covered = np.zeros(spline.n_coef, dtype=bool)
    rows_of = {}
    for (_, cov, block_rows), cis in zip(folded, groups.values()):
        covered[cov] = True
        rows_of.update(zip(cis, block_rows))
    del folded
    spans = []
    for ci, (blo, bhi) in enumerate(ranges):
        for k, (r0, r1) in zip(range(blo, bhi), rows_of[ci]):
            spans.append(BlockSpan(first=k * block_stars, n=min(block_stars, n_solved - k * block_stars),
                                   rows=slice(r0, r1)))
    data = PreparedData(stars=None, solved=None, blocks=spans, normals=None, h=None, x_true=None,
                        spline=spline, true_attitude=true_att, t_ref_jd=settings.t_ref_jd, dead=dead,
                        covered=covered, n_rows=n_rows, naa_band=np.zeros((0, 0)) if naa_band is None else naa_band,
                        sky=sky, cluster={"table": table, "solved_first": solved_first, "n_solved": n_solved,
                                          "n_fov_transits": n_fov_transits})
    data.keep_resident(client, ranges, DaskChunks(client, chunk_futures, rebuild=rebuild))
    return data

