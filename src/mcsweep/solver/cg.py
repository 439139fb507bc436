"""Normal equations of the global solution and their preconditioned conjugate-gradient solution.

Unknowns: the five astrometric parameters of ``n`` stars (Eq. 1 order, mas and mas/yr)
and the attitude spline coefficients (``n_coef x 3``, mas). The normal matrix

    N = [[N_ss + N_p + F, N_sa], [N_as, N_aa]]

(``N_p`` the prior of Eq. 18, ``F`` the frame penalty of :mod:`mcsweep.solver.frame`)
is never formed: :class:`GlobalProblem` applies it as ``A' (A v)`` with one pass over
the measurements (``numpy.bincount`` accumulations, no loop over stars or measurements).

Bombrun et al. (2012, A&A 538, A77) show that AGIS's block iteration is a
preconditioned iterative method and that conjugate gradients accelerate it: the
preconditioner here is the block-diagonal part of ``N`` the AGIS source and attitude
updates invert (per-star ``(N_ss + N_p)^-1`` from :mod:`~mcsweep.solver.source_update`,
the banded ``N_aa^-1`` from :mod:`~mcsweep.solver.attitude_update`). The iteration is
written out (Hestenes & Stiefel 1952, preconditioned form; Golub & Van Loan,
Alg. 11.5.1) so that every iteration logs the update norm in microarcseconds and the
RMS of the normalised measurement residuals.

Convergence criterion: stop when the largest change of any unknown in an iteration is
below ``update_tol_uas`` (default 1e-3 microarcsec = 1 nas, a thousand times below the
smallest error studied) *and* the relative residual ``|b - N x| / |b|`` is below
``rtol``; or after ``max_iter`` iterations (then ``converged = False``).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .attitude_update import BandedAttitudeSolver, attitude_band, attitude_rhs
from .frame import rotation_matrices
from .observations import Observations
from .source_update import source_normals, source_rhs, solve_sources

__all__ = ["GlobalProblem", "ConvergenceRecord", "GlobalSolution", "solve_global", "UAS_PER_MAS"]

UAS_PER_MAS = 1000.0


@dataclasses.dataclass
class ConvergenceRecord:
    """One iteration: update norms [microarcsec], residual RMS, relative residual, wall time."""

    iteration: int
    update_max_uas: float
    update_rms_position_uas: float
    update_rms_attitude_uas: float
    residual_rms: float
    relative_residual: float
    seconds: float


@dataclasses.dataclass
class GlobalSolution:
    """Result of :func:`solve_global`."""

    x: np.ndarray            # (n, 5) stars
    attitude: np.ndarray     # (n_coef, 3) spline coefficients [mas]
    cov: np.ndarray          # (n, 5, 5) per-star covariance, attitude as known
    residuals: np.ndarray    # (m,) normalised measurement residuals
    history: list
    converged: bool


class GlobalProblem:
    """The normal-equations operator of one global solution.

    Parameters
    ----------
    obs : Observations
        Every star must be determinable on its own with the prior (check with
        :func:`~mcsweep.solver.source_update.solve_sources` first).
    prior_diagonal : array_like (5,) or (n, 5)
        Diagonal of ``N_p`` (Eq. 18).
    ra_deg, dec_deg : array_like (n,)
        Star directions (for the frame constraint).
    """

    def __init__(self, obs: Observations, prior_diagonal, ra_deg, dec_deg):
        self.obs = obs
        n = obs.n_stars
        self.prior = np.broadcast_to(np.asarray(prior_diagonal, dtype=float), (n, 5))
        N_src = source_normals(obs)
        _, self.src_inv, ok = solve_sources(N_src, np.zeros((n, 5)), self.prior)
        if not ok.all():
            raise ValueError(f"{int((~ok).sum())} stars have singular source blocks; remove them first")
        self.att = BandedAttitudeSolver(attitude_band(obs))
        self.K = rotation_matrices(ra_deg, dec_deg)
        # Frame penalty weights: one typical star's position (proper-motion) weight per
        # unit of mean rotation, so the constrained directions are as well conditioned
        # as a star (any positive weight gives the same stars for the orientation).
        self.w_pos = float(np.median(N_src[:, 0, 0] + N_src[:, 1, 1])) / (2.0 * n)
        self.w_pm = float(np.median(N_src[:, 3, 3] + N_src[:, 4, 4] + 2 * self.prior[:, 3])) / (2.0 * n)
        self.n_src = 5 * n
        self.n_att = 3 * obs.n_coef
        self.size = self.n_src + self.n_att

    # ------------------------------------------------------------ layout
    def split(self, v):
        """(stars (n, 5), attitude (n_coef, 3)) views of a full vector."""
        return v[:self.n_src].reshape(-1, 5), v[self.n_src:].reshape(-1, 3)

    def join(self, xs, xa) -> np.ndarray:
        return np.concatenate([np.ravel(xs), np.ravel(xa)])

    # ------------------------------------------------------------ products
    def forward(self, v) -> np.ndarray:
        """``A v`` (m,): normalised measurement change for unknowns ``v``."""
        xs, xa = self.split(v)
        o = self.obs
        out = np.einsum("mi,mi->m", o.src, xs[o.star])
        for k in range(4):
            out += o.bval[:, k] * np.einsum("mi,mi->m", o.att, xa[o.j0 + k])
        return out

    def adjoint(self, r) -> np.ndarray:
        """``A' r`` for normalised residuals ``r`` (m,)."""
        return self.join(source_rhs(self.obs, r), attitude_rhs(self.obs, r))

    def frame_penalty(self, xs) -> np.ndarray:
        """``F x`` (n, 5): the penalty of the zero-mean rotation and spin constraint."""
        out = np.zeros_like(xs)
        c_pos = np.einsum("nij,ni->j", self.K, xs[:, 0:2])
        c_pm = np.einsum("nij,ni->j", self.K, xs[:, 3:5])
        out[:, 0:2] = self.w_pos * (self.K @ c_pos)
        out[:, 3:5] = self.w_pm * (self.K @ c_pm)
        return out

    def apply(self, v, fwd=None) -> np.ndarray:
        """``N v``; ``fwd`` = ``A v`` if already known."""
        fwd = self.forward(v) if fwd is None else fwd
        y = self.adjoint(fwd)
        xs, xa = self.split(v)
        ys, ya = self.split(y)
        ys += self.prior * xs + self.frame_penalty(xs)
        ya[~self.att.free] = xa[~self.att.free]  # unobserved coefficients: identity rows
        return y

    def rhs(self, h) -> np.ndarray:
        """``A' h`` with unobserved attitude coefficients held at zero."""
        b = self.adjoint(h)
        _, ba = self.split(b)
        ba[~self.att.free] = 0.0
        return b

    def precondition(self, r) -> np.ndarray:
        """Block-diagonal preconditioner: the AGIS source and attitude updates."""
        rs, ra = self.split(r)
        zs = np.einsum("nij,nj->ni", self.src_inv, rs)
        return self.join(zs, self.att.solve(ra))


def solve_global(problem: GlobalProblem, h, *, rtol: float = 1e-10, update_tol_uas: float = 1e-3,
                 max_iter: int = 500, min_iter: int = 2, log=None) -> GlobalSolution:
    """Preconditioned conjugate gradients on ``N x = A' h`` from ``x = 0`` (module notes).

    Parameters
    ----------
    problem : GlobalProblem
    h : array_like (m,)
        Normalised measurements (observed minus computed from the starting values:
        the scanning-law attitude and zero corrections).
    rtol, update_tol_uas, max_iter, min_iter : keyword-only
        Convergence criterion (module notes).
    log : callable, optional
        Called with each :class:`ConvergenceRecord`.
    """
    h = np.asarray(h, dtype=float)
    b = problem.rhs(h)
    b_norm = float(np.linalg.norm(b)) or 1.0
    x = np.zeros(problem.size)
    r = b.copy()
    res = h.copy()  # measurement residuals h - A x
    z = problem.precondition(r)
    p = z.copy()
    rz = float(r @ z)
    history, converged = [], False
    t0 = time.perf_counter()
    for it in range(1, max_iter + 1):
        fp = problem.forward(p)
        q = problem.apply(p, fwd=fp)
        pq = float(p @ q)
        if pq <= 0.0:  # exact solution reached (or loss of positive definiteness)
            break
        alpha = rz / pq
        x += alpha * p
        r -= alpha * q
        res -= alpha * fp
        step_s, step_a = problem.split(alpha * p)
        rec = ConvergenceRecord(
            iteration=it,
            update_max_uas=UAS_PER_MAS * float(np.max(np.abs(alpha * p))),
            update_rms_position_uas=UAS_PER_MAS * float(np.sqrt(np.mean(np.sum(step_s[:, :2] ** 2, axis=1)))),
            update_rms_attitude_uas=UAS_PER_MAS * float(np.sqrt(np.mean(np.sum(step_a ** 2, axis=1)))),
            residual_rms=float(np.sqrt(np.mean(res ** 2))) if res.size else 0.0,
            relative_residual=float(np.linalg.norm(r)) / b_norm,
            seconds=time.perf_counter() - t0)
        history.append(rec)
        if log is not None:
            log(rec)
        if it >= min_iter and rec.update_max_uas < update_tol_uas and rec.relative_residual < rtol:
            converged = True
            break
        z = problem.precondition(r)
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    xs, xa = problem.split(x)
    return GlobalSolution(x=xs.copy(), attitude=xa.copy(), cov=problem.src_inv.copy(), residuals=res,
                          history=history, converged=converged)
