"""The preconditioned conjugate-gradient iteration of the global solution.

PCG on the full system ``N x = A'h`` (Bombrun et al. 2012, A&A 538, A77; the normal
equations of :mod:`~mcsweep.solver.problem`) with the symmetric block Gauss-Seidel
preconditioner of :mod:`~mcsweep.solver.schur_preconditioner`. The operator ``N`` itself is
applied exactly: an elimination of the stars inside the operator would be ruined by
rounding (a star seen once under a 1000 mas prior has a 5 x 5 block of condition ~1e10).

Each iteration is two passes over the measurements in blocks of stars (the two sweeps of
the preconditioner; ``N z`` is formed in the second, ``N p`` by recursion,
``q = N z + beta q``), chunk tasks of :mod:`~mcsweep.solver.tasks` summed in the fixed order
of :mod:`~mcsweep.solver.reduction` (:class:`~mcsweep.solver.executors.ChunkPasses`), so the
solution is bit-identical for any chunking, backend and number of workers. The attitude
vectors of a pass are summed per leaf of blocks (reduction, "Leaves").

Where the vectors live. Every star vector of the iteration is held chunk by chunk where the
chunk's measurements are (in-process, a forked worker of :mod:`~mcsweep.solver.resident`,
or a Dask worker of :mod:`~mcsweep.solver.dask_resident`) and updated there. The driver
holds the attitude vectors and the banded Schur factor; an iteration exchanges with each
chunk the step ``alpha``, the attitude vector ``z_a``, the six frame sums and ``beta`` one
way, and two attitude-sized vectors and a few per-block sums (dot products, convergence
numbers) the other, in three rounds (forward sweep with the step, back sweep, new
direction). The star vectors reach the driver once, as the solution (not at all for a
:class:`~mcsweep.solver.problem.ResidentProblem`). Dot products are sums of per-block dots
in the fixed tree, so their rounding differs from a single dot over the whole vector (the
same for every backend).

Bordered unknowns. A few unknowns that every measurement may depend on (a calibration,
:mod:`~mcsweep.solver.calibration`; partials ``C (m, k)``, no prior, no frame) border the
system: ``[[N, G], [G', D]]`` with ``G = A'C``, ``D = C'C``. ``G`` is made once, in the setup
pass, as the right-hand side each column would give as measurements; its stars' rows stay
with their chunks, its attitude rows on the driver. An iteration then needs no further pass
over the measurements: the chunks add ``G_s z_c`` to ``N z`` and return ``G_s' z_s`` with
their dots, the driver does the rest, and the preconditioner takes the bordered unknowns by
``D^-1``. The preconditioned matrix so differs from the unbordered one by rank ``<= 2k``,
which costs CG at most ``2k`` more iterations in exact arithmetic, however nearly degenerate
the bordered unknowns are with the rest (the basic-angle variation with the parallax zero
point, Butkevich et al. 2017, A&A 603, A45).

Starting attitude. A start ``a0`` makes PCG start from ``x0 = (0, a0)``: each chunk's setup
takes ``h - A_a a0`` for its measurements, so the iteration solves for the correction from
``x0``, and the solution is ``a0`` plus it (the bordered unknowns' right-hand side loses
``G_a' a0``). The stars need no start of their own: the first preconditioner step gives them
their update given the attitude, ``B^-1 (r_s - N_sa z_a)``. Any start gives the
least-squares solution to the stopping rule's tolerance (:mod:`~mcsweep.solver.stopping`);
a start near it removes most of the error the weakly determined knots would otherwise carry
from zero (measured: docs/solver_design.md, "Starting attitude").
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .executors import ChunkPasses
from .reduction import pairwise_dot
from .schur_preconditioner import SchurPreconditioner
from .stopping import UAS_PER_MAS, ConvergenceRecord, remaining_error
from .tasks import add_setup, back_task, direction_task, forward_task, residual_task, setup_task

__all__ = ["GlobalSolution", "RightHandSide", "PcgSteps", "pcg", "setup_pass", "iterate", "final_pass"]


@dataclasses.dataclass
class GlobalSolution:
    """Result of :func:`~mcsweep.solver.solve.solve_global`."""

    x: np.ndarray            # (n, 5) stars
    attitude: np.ndarray     # (n_coef, 3) spline coefficients [mas]
    cov: np.ndarray          # (n, 5, 5) per-star covariance, attitude as known (the problem's; read only)
    residuals: np.ndarray | None  # (m,) normalised measurement residuals h - A x (None unless asked)
    residual_rms: float      # RMS of the normalised residuals (from the explicit final pass)
    history: list
    converged: bool
    border: np.ndarray | None = None  # (k,) the bordering unknowns (solve_global's ``border``), if any


@dataclasses.dataclass
class RightHandSide:
    """What the setup pass leaves with the driver: the attitude's and the bordered unknowns'
    right-hand sides ``b_a``, ``b_c = C'h``, the bordered block ``D = C'C`` and the attitude
    rows of its columns ``G_a = A_a'C`` (without bordered unknowns, ``k = 0``: empty, whose dots
    add an exact 0.0 to every sum), ``|b|`` and ``h'h``."""

    b_a: np.ndarray
    b_c: np.ndarray
    D: np.ndarray
    G_a: np.ndarray
    b_norm: float
    hh: float


def setup_pass(pb, chunks, passes: ChunkPasses, start, border_normals) -> RightHandSide:
    """The setup pass: the right-hand side, the stars' vectors on the workers (module notes).
    The setup's numbers are only added element by element (no SIMD reduction whose rounding
    could depend on where an unpickled array sits), so they are summed as received, without
    fresh copies, each chunk's dropped once in the tree."""
    stars = [slice(bl[0].first, bl[-1].first + bl[-1].n) for bl in chunks]
    (glob,) = passes.summed(setup_task, [(i, None, None, pb.frame_means, passes.leaves[i], start)
                                         if pb.stars_with_chunks else
                                         (i, pb.prior[sl], pb.K[sl], pb.frame_weights[sl], passes.leaves[i], start)
                                         for i, sl in zip(passes.n_ch, stars)], [("leaves", add_setup)], fresh=False)
    free = pb.free
    b_a = np.where(free, glob["b_a"], 0.0)
    # the bordered unknowns (module notes): right-hand side b_c = C'h, their block D = C'C,
    # the attitude's rows of their columns G_a = A_a'C; the stars' rows G_s stay with the chunks.
    bordered = border_normals is not None
    b_c, D = border_normals if bordered else (np.zeros(0), np.zeros((0, 0)))
    G_a = np.where(free, glob["g_a"], 0.0) if bordered else np.zeros((0,) + b_a.shape)
    if start is not None:  # C'(h - A_a start): the chunks' right-hand sides were made from the same difference
        b_c = b_c - np.array([pairwise_dot(g, start) for g in G_a])
    b_norm = float(np.sqrt(glob["bb"] + pairwise_dot(b_a, b_a) + pairwise_dot(b_c, b_c))) or 1.0
    return RightHandSide(b_a=b_a, b_c=b_c, D=D, G_a=G_a, b_norm=b_norm, hh=glob["hh"])


class PcgSteps:
    """One iteration's passes over the chunks and the driver's share of them: the forward
    sweep with the step (:meth:`forward`) and the preconditioner's application with ``N z``
    and the new direction (:meth:`precondition`)."""

    def __init__(self, pb, passes: ChunkPasses, rhs: RightHandSide, bordered: bool):
        self.passes, self.bordered = passes, bordered
        self.free, self.w = pb.free, (pb.w_pos, pb.w_pm)
        self.G_a, self.D = rhs.G_a, rhs.D
        self.D_inv = np.linalg.inv(rhs.D)
        self.schur = SchurPreconditioner(pb, passes)

    def forward(self, alpha):
        """The step ``alpha`` (None: none yet) applied on the workers, then the first sweep:
        its attitude part ``w_a``, the convergence numbers and the largest star step."""
        p = self.passes
        return tuple(p.summed(forward_task, [(i, alpha, p.leaves[i]) for i in p.n_ch],
                              [("leaves", None), ("blocks", None), ("max", None)]))

    def precondition(self, r_a, r_c, w_a, beta):
        """``z = M^-1 r`` (symmetric block Gauss-Seidel with the banded Schur block; the first
        sweep's attitude part ``w_a`` from the forward task; the bordered unknowns by ``D^-1``),
        its ``r'z``, then on the workers ``N z`` and the new direction: returns ``z_a``,
        ``(N z)_a``, ``z_c``, ``(N z)_c``, ``r'z``, ``beta`` (``beta(r'z)`` of the callable
        given, None for the first direction) and the stars' share of ``p'q``."""
        p, free, G_a, D = self.passes, self.free, self.G_a, self.D
        z_a = self.schur.attitude_step(r_a, w_a)
        nz_a, numbers = p.summed(back_task, [(i, z_a, p.leaves[i]) for i in p.n_ch],
                                 [("leaves", None), ("blocks", None)])
        nz_a[~free] = z_a[~free]
        # N z's border rows G_s'z_s + G_a'z_a + D z_c (the chunks' dots after the frame sums); its
        # border columns G z_c
        z_c = self.D_inv @ r_c
        nz_c = numbers[7:] + np.array([pairwise_dot(g, z_a) for g in G_a]) + D @ z_c
        for g, c in zip(G_a, z_c):
            nz_a += c * g
        rz = float(numbers[0]) + pairwise_dot(r_a, z_a) + pairwise_dot(r_c, z_c)
        beta = None if beta is None else beta(rz)
        (pq_s,) = p.summed(direction_task, [(i, numbers[1:7], beta, self.w, z_c if self.bordered else None)
                                            for i in p.n_ch], [("blocks", None)])
        return z_a, nz_a, z_c, nz_c, rz, beta, float(pq_s)


def _record(pb, rhs: RightHandSide, it, alpha, rz, step_a, step_c, x_a, x_c, r_a, r_c, numbers, largest_s,
            error, t0) -> ConvergenceRecord:
    """The iteration's :class:`~mcsweep.solver.stopping.ConvergenceRecord` from the driver's
    vectors and the chunks' convergence numbers."""
    m = pb.n_measurements
    xbr, xex, step_pos2, rr_s = (float(v) for v in numbers)
    # |h - A x|^2 = h'h - 2 x'b + x'A'A x with A'A x = b - r - (N_p + F) x_s (A, x, b and r
    # with the bordered unknowns)
    res2 = rhs.hh - (xbr + pairwise_dot(x_a, rhs.b_a + r_a) + pairwise_dot(x_c, rhs.b_c + r_c)) - xex
    return ConvergenceRecord(
        iteration=it,
        update_max_uas=UAS_PER_MAS * max(float(np.max(np.abs(step_a), initial=0.0)), largest_s,
                                         float(np.max(np.abs(step_c), initial=0.0))),
        update_rms_position_uas=UAS_PER_MAS * float(np.sqrt(step_pos2 / max(pb.n_stars, 1))),
        update_rms_attitude_uas=UAS_PER_MAS * float(np.sqrt(np.mean(np.sum(step_a ** 2, axis=1)))),
        residual_rms=float(np.sqrt(max(res2, 0.0) / m)) if m else 0.0,
        relative_residual=float(np.sqrt(rr_s + pairwise_dot(r_a, r_a) + pairwise_dot(r_c, r_c))) / rhs.b_norm,
        seconds=time.perf_counter() - t0, energy_decrease=alpha * rz, error_estimate=error)


def iterate(pb, steps: PcgSteps, rhs: RightHandSide, *, rtol, update_tol_uas, error_tol, max_iter, min_iter,
            log, start) -> tuple:
    """The PCG loop from zero (the start is in the right-hand sides) until the stopping rule
    (:mod:`~mcsweep.solver.stopping`) or ``max_iter``: returns the attitude and bordered
    unknowns' solutions (the stars' stay with the chunks), the history and whether it
    converged."""
    x_a, x_c = np.zeros_like(rhs.b_a), np.zeros_like(rhs.b_c)
    r_a, r_c = rhs.b_a.copy(), rhs.b_c.copy()
    w_a, _, _ = steps.forward(None)
    p_a, q_a, p_c, q_c, rz, _, pq_s = steps.precondition(r_a, r_c, w_a, None)
    p_a = p_a.copy()
    history, converged = [], False
    energies = []  # squared N-norms of the steps, for the error estimate
    t0 = time.perf_counter()
    for it in range(1, max_iter + 1):
        pq = pq_s + pairwise_dot(p_a, q_a) + pairwise_dot(p_c, q_c)
        if not pq > 0.0:  # exact solution reached, loss of positive definiteness, or not finite
            break
        alpha = rz / pq
        step_a = alpha * p_a
        x_a += step_a
        r_a -= alpha * q_a
        step_c = alpha * p_c
        x_c += step_c
        r_c -= alpha * q_c
        w_a, numbers, largest_s = steps.forward(alpha)
        energies.append(alpha * rz)
        # From a starting attitude the first step also sets the stars (the start holds none of
        # them): a one-off, not part of the decay the extrapolation follows (stopping's notes)
        error = remaining_error(energies if start is None else energies[1:]) if error_tol is not None \
            else float("nan")
        rec = _record(pb, rhs, it, alpha, rz, step_a, step_c, x_a, x_c, r_a, r_c, numbers, largest_s, error, t0)
        history.append(rec)
        if log is not None:
            log(rec)
        if it >= min_iter and (error <= error_tol if error_tol is not None else
                               rec.update_max_uas < update_tol_uas and rec.relative_residual < rtol):
            converged = True
            break
        if it == max_iter:
            break
        z_a, nz_a, z_c, nz_c, rz_new, beta, pq_s = steps.precondition(r_a, r_c, w_a, lambda rz_new: rz_new / rz)
        p_a = z_a + beta * p_a
        q_a = nz_a + beta * q_a   # N p without another pass
        p_c = z_c + beta * p_c
        q_c = nz_c + beta * q_c
        rz = rz_new
    return x_a, x_c, history, converged


def final_pass(pb, passes: ChunkPasses, x_a, x_c, residuals: bool, bordered: bool) -> tuple:
    """The residual pass of the solution: the measurements' residuals (None unless
    ``residuals``), their RMS and the stars' solution (None when it stays with the chunks)."""
    m = pb.n_measurements
    out = passes.ordered(residual_task, [(i, x_a, residuals, not pb.stars_with_chunks,
                                          x_c if bordered else None) for i in passes.n_ch])
    res_all = None
    if residuals:
        res_all = np.empty(m)
        for b, rb in zip(pb.blocks, [r for o in out for r in o[0]]):
            res_all[b.rows] = rb
    ss = passes.total(o[1] for o in out)
    x_s = None if pb.stars_with_chunks else np.concatenate([o[2] for o in out]) if out else np.zeros((0, 5))
    return res_all, (float(np.sqrt(ss / m)) if m else float("nan")), x_s


def pcg(pb, chunks, run, *, rtol, update_tol_uas, error_tol, max_iter, min_iter,
        log, residuals, border_normals=None, start=None, reduced=None) -> GlobalSolution:
    """The PCG solution of :func:`~mcsweep.solver.solve.solve_global`; ``run(fn, items)`` runs
    chunk tasks whose items are ``(ci, *rest)`` on the executor that holds chunk ``ci`` and its
    state. ``border_normals``: ``(C'h, C'C)`` of the bordered unknowns, whose columns the
    chunks' states hold (None: none). ``start``: the starting attitude (None: zero).
    ``reduced``: an executor that sums the chunks' outputs where they are
    (:class:`~mcsweep.solver.executors.ChunkPasses`)."""
    passes = ChunkPasses(pb, chunks, run, reduced)
    rhs = setup_pass(pb, chunks, passes, start, border_normals)
    bordered = border_normals is not None
    steps = PcgSteps(pb, passes, rhs, bordered)
    x_a, x_c, history, converged = iterate(pb, steps, rhs, rtol=rtol, update_tol_uas=update_tol_uas,
                                           error_tol=error_tol, max_iter=max_iter, min_iter=min_iter, log=log,
                                           start=start)
    if start is not None:
        x_a = x_a + start
    res_all, rms, x_s = final_pass(pb, passes, x_a, x_c, residuals, bordered)
    return GlobalSolution(x=x_s, attitude=x_a, cov=pb.src_inv, residuals=res_all, residual_rms=rms,
                          history=history, converged=converged, border=x_c if bordered else None)
