"""The global solution: :func:`solve_global`, PCG on chunks of the problem wherever they run.

:func:`solve_global` checks its arguments, cuts the problem's blocks into chunks
(:meth:`~mcsweep.solver.problem.GlobalProblem.chunks`), puts each chunk with its
measurements and a state of its own on an executor (in this process, forked workers of
:mod:`~mcsweep.solver.resident`, or a Dask cluster's workers of
:mod:`~mcsweep.solver.dask_resident`) and runs the iteration of :mod:`~mcsweep.solver.pcg`
there; a solution whose chunks were lost with a worker is restarted
(:class:`~mcsweep.solver.executors.ChunksLost`). Results do not depend on the executor, the
chunking or the number of workers: every sum is taken in the fixed tree of
:mod:`~mcsweep.solver.reduction`.

The unknowns, preconditioner and stopping rule: :mod:`~mcsweep.solver.problem`,
:mod:`~mcsweep.solver.schur_preconditioner` and :mod:`~mcsweep.solver.stopping`; "module
notes" below means those of :mod:`~mcsweep.solver.pcg` ("Bordered unknowns", "Starting
attitude") and of :mod:`~mcsweep.solver.stopping` (the convergence criterion).
"""

from __future__ import annotations

import numpy as np

from .dask_resident import DaskChunks
from .executors import ChunksLost, HeldChunks, retried
from .pcg import GlobalSolution, pcg
from .problem import GlobalProblem
from .reduction import pairwise_dot, share_of

__all__ = ["solve_global"]


def solve_global(problem: GlobalProblem, h, *, rtol: float = 1e-10, update_tol_uas: float = 1e-3,
                 error_tol: float | None = None, max_iter: int = 500,
                 min_iter: int = 2, log=None, chunk_stars: int | None = None,
                 residuals: bool = True, workers: int = 1, dask_client=None,
                 resident_chunks=None, border=None, attitude_start=None) -> GlobalSolution:
    """Solve ``N x = A' h`` by PCG from ``x = 0``, or from the attitude ``attitude_start`` (module notes).

    Parameters
    ----------
    problem : GlobalProblem
    h : array_like (m,) or None
        Normalised measurements (observed minus computed from the starting values:
        the scanning-law attitude and zero corrections), in observation order; None when
        they are kept with ``resident_chunks`` (built on the workers).
    rtol, update_tol_uas, error_tol, max_iter, min_iter : keyword-only
        Convergence criterion (module notes): with ``error_tol`` (in units of the formal
        uncertainty of every estimated quantity) the energy criterion, and ``rtol`` and
        ``update_tol_uas`` are not used.
    log : callable, optional
        Called with each :class:`~mcsweep.solver.stopping.ConvergenceRecord` (after a restart, from iteration 1 again).
    chunk_stars : int, optional, keyword-only
        Most stars per chunk task (rounded down to a power of two of blocks); default: as
        many as the workers' equal shares of the blocks allow (a few chunks per worker, so a
        pass returns a few attitude-sized vectors per worker, not one per block). Results do
        not depend on it.
    residuals : bool, keyword-only
        Return the residual of every measurement (``GlobalSolution.residuals``, 8 bytes
        per measurement); ``False`` keeps only their RMS.
    workers : int, keyword-only
        Forked processes that keep their share of the chunks and of the star vectors
        (:mod:`~mcsweep.solver.resident`); 1 (default) or no ``fork``: in-process. Results
        do not depend on it. (A map-like executor, one that sends a task's data with every
        call, cannot keep the star vectors between passes and is not accepted.)
    dask_client : distributed.Client, optional, keyword-only
        Every pass on a Dask cluster whose workers keep the chunks and their star vectors
        (:class:`~mcsweep.solver.dask_resident.DaskChunks`: scattered once, then only
        attitude-sized vectors travel); overrides ``workers``. Results do not depend on it.
    resident_chunks : ChunkHolder, optional, keyword-only
        The chunks where they stay (a cluster's workers; this process, ``HeldChunks``): chunk
        ``ci`` the blocks of ``problem.chunks(chunk_stars, shares=resident_chunks.shares)[ci]``.
    border : array_like (m, k), optional, keyword-only
        Normalised partials of ``k`` further unknowns that every measurement may depend on
        (a calibration, :mod:`~mcsweep.solver.calibration`), without prior or frame constraint,
        solved with the rest (module notes, "Bordered unknowns"; ``GlobalSolution.border``).
        Needs ``h``; resident chunks hold their blocks' rows already (``state["border"]``).
    attitude_start : array_like (n_coef, 3), optional, keyword-only
        Attitude coefficients [mas] PCG starts from (module notes, "Starting attitude"), e.g.
        the solution of the same data under another prior; coefficients without data are
        ignored (held at zero). The solution, residuals and stopping rule are those of the
        whole solution, the start included.
    """
    if h is None and resident_chunks is None:
        raise ValueError("the measurements h are needed unless they are on the workers (resident_chunks)")
    if h is not None:
        h = np.asarray(h, dtype=float)
        if h.size != problem.n_measurements:
            raise ValueError(f"h has {h.size} measurements, the problem {problem.n_measurements}")
    shares = resident_chunks.shares if resident_chunks is not None else \
        1 if dask_client is not None else max(1, int(workers))
    ranges = problem.chunks(chunk_stars, shares=shares)
    chunks = [problem.blocks[lo:hi] for lo, hi in ranges]
    # views when the rows are slices (in_block_order); None: kept with the resident chunks
    hs = None if h is None else [[h[b.rows] for b in bl] for bl in chunks]
    if resident_chunks is None and dask_client is not None:
        resident_chunks = DaskChunks.scatter(dask_client, list(zip(chunks, hs)))
    if error_tol is not None and not error_tol > 0:
        raise ValueError(f"error_tol={error_tol}: expected a positive fraction of the formal uncertainties")
    kw = dict(rtol=rtol, update_tol_uas=update_tol_uas, error_tol=error_tol,
              max_iter=max_iter, min_iter=min_iter, log=log, residuals=residuals)
    if attitude_start is not None:
        kw["start"] = _attitude_start(problem, attitude_start)
    states = [{} for _ in chunks]
    if border is not None:
        kw["border_normals"] = _border(border, h, chunks, None if resident_chunks is not None else states)
    if resident_chunks is None:
        owners = [share_of(lo, len(problem.blocks), shares) for lo, _ in ranges]
        # the chunks and their states are these very objects (or forked copies of them)
        resident_chunks = HeldChunks(list(zip(chunks, hs, states)), workers, owners)
        with resident_chunks.solving(keep=()) as run:
            return pcg(problem, chunks, run, **kw)
    return _solve_resident(problem, chunks, resident_chunks, kw)


def _attitude_start(problem, attitude_start) -> np.ndarray:
    """The starting attitude, checked, with the coefficients without data at zero."""
    start = np.asarray(attitude_start, dtype=float)
    if start.shape != (problem.n_coef, 3) or not np.isfinite(start).all():
        raise ValueError(f"attitude_start has shape {start.shape}: expected ({problem.n_coef}, 3), finite")
    return np.where(problem.free, start, 0.0)


def _border(border, h, chunks, states) -> tuple[np.ndarray, np.ndarray]:
    """``(C'h, C'C)`` of the bordered unknowns' partials ``C = border (m, k)``, put block by block
    in the chunks' ``states`` (None: resident chunks, which hold them already)."""
    if h is None:
        raise ValueError("border unknowns are solved with the measurements h given")
    border = np.asarray(border, dtype=float).reshape(h.size, -1)
    for st, bl in zip(states or (), chunks):
        st["border"] = [np.ascontiguousarray(border[b.rows]) for b in bl]
    # C' h and C' C by numpy's pairwise sums (pairwise_dot): the same bits for any chunking
    return (np.array([pairwise_dot(c, h) for c in border.T]),
            np.array([[pairwise_dot(a, c) for c in border.T] for a in border.T]))


def _solve_resident(problem, chunks, resident_chunks, kw) -> GlobalSolution:
    """The solution on chunks kept where they are: held in this process (their ``solving``
    executor: here or on forked workers, the stars' solution left in their states), or on a
    cluster's workers, restarted from its first pass after lost chunks
    (:class:`~mcsweep.solver.executors.ChunksLost`) up to
    :data:`~mcsweep.solver.executors.MAX_RESTARTS` times."""
    def attempt():
        with resident_chunks.solving() as run:
            return pcg(problem, chunks, run, reduced=resident_chunks.reduced, **kw)

    return retried(attempt, lambda exc: isinstance(exc, ChunksLost))
