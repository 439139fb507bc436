"""A basic-angle variation solved with the stars and the attitude (issue 24, candidate 3).

AGIS solves calibration unknowns together with the sources and the attitude (its C block:
Lindegren et al. 2012, A&A 538, A78); the paper's global solutions came from AGISLab, the
same group's simulator of AGIS. One calibration matters here above the others: a variation of the basic
angle Gamma between the two fields of view with the heliotropic spin phase Omega,

    delta Gamma(t) = sum_{j = 1..K} (c_j cos j Omega + s_j sin j Omega),

which shifts every AL measurement of the preceding field by +delta Gamma / 2 and of the
following field by -delta Gamma / 2 (AC measurements do not see it). Its ``cos Omega`` term
cannot be told apart from a shift of every parallax (Butkevich et al. 2017, A&A 603, A45):
at a transit the AL effect of a parallax ``d plx`` is ``-d plx sin xi sin(Omega' +- Gamma/2)``
(xi the solar aspect angle, Omega' the spin phase from the Sun's direction), whose part
common to both fields is a rotation of the attitude about the spin axis and whose
difference is ``delta Gamma = -2 d plx sin xi sin(Gamma/2) cos Omega'``; the AC effect,
``d plx cos xi``, is the same in both fields, a rotation about the SRS y axis. So with these
unknowns the data no longer fix the parallax zero point: the priors do (in the paper's
solution every star has one, centred on zero while every true parallax is positive), and
whatever else the near-degenerate mode holds takes the bias with it. The test
``test_a_shift_of_every_parallax_is_a_basic_angle_variation`` checks the degeneracy on the
scanning law's own geometry.

How it is solved. The ``n_cal = 2 K`` calibration unknowns ``c`` couple to every
measurement, so they are not put into the banded blocks of :mod:`.cg`: with ``A`` the
design of the stars and the attitude, ``A_c`` that of the calibration (normalised like the
measurements) and ``N`` the normal matrix of :mod:`.cg` (prior and frame included), the
bordered system

    [[N, A' A_c], [A_c' A, A_c' A_c]] [x; c] = [A' h; A_c' h]

is solved through the calibration's Schur complement: ``x_0 = N^-1 A' h`` and
``X_l = N^-1 A' a_l`` for every column ``a_l`` of ``A_c`` (each one :func:`.cg.solve_global`
with the column as its measurements), then with the residuals ``r_0 = h - A x_0`` and
``r_l = a_l - A X_l``

    S c = A_c' r_0,   S_kl = a_k' r_l   (= A_c' A_c - A_c' A N^-1 A' A_c),

and ``x = x_0 - X c``; the residuals of the whole solution are ``r_0 - sum_l c_l r_l``. The
extra cost is ``n_cal`` more solutions of the same normal equations, and the residual of
each (8 bytes per measurement) held until the end. The per-star covariances stay those of
:mod:`.cg` (attitude and calibration as known), as the paper's Table 3 evaluates them.

Accuracy. Each solution stops on the energy rule of :mod:`.cg`: its error below a fraction
of the formal uncertainties in the norm of ``N`` (``tau``). With ``e`` the error of
``x_0 - X c`` (``e = e_0 - sum_l c_l E_l`` from the solutions' errors ``e_0``, ``E_l``), the
error of the whole solution in the norm of the bordered system is (exactly, with ``c`` solved
from ``S`` as made, not from its symmetric part)

    sqrt(e' N e + (A_c' A e)' S^-1 (A_c' A e))  <=  |e|_N / sin theta,

``theta`` the smallest principal angle between the calibration columns and the span of the
stars' and attitude's design in the metric of ``N`` (``sin^2 theta`` is the smallest
eigenvalue of ``S`` relative to ``A_c' A_c``). Near the degeneracy above ``theta`` is small.
So the columns are solved first (``tau``), then the data with ``tau sin theta / 2``; if
``sum |c_l|`` [mas] times the columns' tolerance exceeds that too, the columns are solved
again with ``tau sin theta / (2 sum |c_l|)`` (and the data again if ``theta`` moved): then
``|e|_N <= tau sin theta`` and the whole solution is within ``tau`` of the exact one, the
rule every solution of the experiment keeps (as far as :mod:`.cg`'s estimate of each
solution's error, an extrapolation, holds). ``amplification`` is ``1 / sin theta``.
Checked against a direct solve of the bordered system in ``tests/solver/test_calibration.py``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..scanning.attitude import attitude_for

__all__ = ["BasicAngleColumns", "basic_angle_columns", "CalibratedSolution", "CalibrationNotDetermined",
           "solve_with_calibration"]


#: Rounds of solutions at most: the columns' solutions are made again, tighter, when the
#: fitted calibration turns out large (module notes, "Accuracy"); one more is rarely needed.
MAX_ROUNDS = 3
#: Tightening beyond the bound, so that the slightly different ``c`` of the new round meets it.
TIGHTENING_MARGIN = 0.2
#: Smallest ``sin^2 theta`` accepted (module notes, "Accuracy"): below it the data would have
#: to be solved to 5e-7 of the asked tolerance or finer, far past what PCG reaches in
#: practice, and the calibration counts as not determined. A choice (the experiment's
#: smallest, at 25 FoV transits per knot under 1000 mas, was 5.6e-5).
MIN_SIN2_THETA = 1e-12


class CalibrationNotDetermined(np.linalg.LinAlgError):
    """The calibration cannot be solved to the asked accuracy: its Schur complement is not
    (or only to rounding) positive definite, some combination of the calibration unknowns
    not fixed by the data and the priors; or its rounds of solutions ran out."""


@dataclasses.dataclass
class BasicAngleColumns:
    """The calibration design of a basic-angle variation with ``harmonics`` harmonics of the
    spin phase, kept compactly: per measurement the spin phase ``omega`` [rad] and the weight
    ``+1/2`` (preceding field) or ``-1/2`` (following) over the AL uncertainty [1/mas], zero for
    AC measurements; column ``2 (j - 1)`` is ``weight cos j omega``, ``2 j - 1`` its ``sin``."""

    omega: np.ndarray
    weight: np.ndarray
    harmonics: int

    @property
    def n_cal(self) -> int:
        return 2 * self.harmonics

    def column(self, k: int) -> np.ndarray:
        j = k // 2 + 1
        return self.weight * (np.cos(j * self.omega) if k % 2 == 0 else np.sin(j * self.omega))

    def names(self) -> list[str]:
        return [f"{'cos' if k % 2 == 0 else 'sin'} {k // 2 + 1} Omega" for k in range(self.n_cal)]


def basic_angle_columns(tcb_jd, following, sigma_al_mas, is_ac, law, harmonics: int) -> BasicAngleColumns:
    """:class:`BasicAngleColumns` of measurements at ``tcb_jd`` in the ``following`` field (bool)
    with AL uncertainty ``sigma_al_mas``; ``is_ac`` rows get weight zero; ``law``: the
    scanning law whose spin phase the variation follows."""
    t = np.asarray(tcb_jd, dtype=float)
    _, _, omega = attitude_for(law).lam_nu_omega(t)
    sign = np.where(np.asarray(following, dtype=bool), -0.5, 0.5)
    weight = np.where(np.asarray(is_ac, dtype=bool), 0.0, sign / np.asarray(sigma_al_mas, dtype=float))
    return BasicAngleColumns(omega=np.asarray(omega, dtype=float), weight=weight, harmonics=int(harmonics))


@dataclasses.dataclass
class CalibratedSolution:
    """The solution with calibration unknowns: ``solution`` (a :class:`.cg.GlobalSolution`
    whose ``x``, ``attitude`` and residuals are those of the whole system and whose
    ``history`` holds every solution's iterations one after the other), the calibration ``c``
    [mas], each solution's name and history, the condition number of ``S``, and
    ``amplification``, ``1 / sin theta`` (module notes, "Accuracy")."""

    solution: object
    c: np.ndarray
    solutions: list  # (name, history) of every solution made, in order: columns, data, columns again...
    condition: float
    amplification: float

    @property
    def iterations(self) -> list:
        return [len(hist) for _, hist in self.solutions]

    @property
    def seconds(self) -> float:
        """Wall time of all the solutions' iterations (each history's clock starts at zero)."""
        return float(sum(hist[-1].seconds for _, hist in self.solutions if hist))


def solve_with_calibration(solve, h, columns: BasicAngleColumns, *, log=None,
                           scalable: bool = True) -> CalibratedSolution:
    """Solve stars, attitude and the calibration ``columns`` together (module notes).

    ``solve(h, log, scale)`` is one solution of the normal equations of the stars and attitude
    for measurements ``h`` (:func:`.cg.solve_global` with the problem and the executor
    bound), asked to return its residuals, with its error tolerance multiplied by ``scale``.
    The tolerances are set so that the whole solution meets the one asked (module notes,
    "Accuracy"): the columns' solutions are made again, tighter, when ``c`` turns out large.
    ``scalable=False`` (a stopping rule without a relative tolerance, which ``scale`` leaves
    alone): one solution each, at the rule as given.
    """
    n = columns.n_cal
    C = np.column_stack([columns.column(k) for k in range(n)]) if n else np.zeros((len(h), 0))
    D = C.T @ C
    solutions, seconds = [], 0.0  # (name, history) of every solution, in the order made
    col_scale, base, base_scale = 1.0, None, math.inf
    for _ in range(MAX_ROUNDS):
        sols = []
        for k in range(n):
            sols.append(solve(C[:, k], log, col_scale))
            solutions.append((f"column {columns.names()[k]}", sols[-1].history))
        R = np.column_stack([sl.residuals for sl in sols]) if n else np.zeros((len(h), 0))
        for sl in sols:
            sl.residuals = None
        S = C.T @ R  # S_kl = a_k' r_l: solved as made, its symmetric part for the spectrum
        lam = _generalized_eigvalsh(0.5 * (S + S.T), D) if n else np.ones(1)
        if not lam[0] >= MIN_SIN2_THETA:
            raise CalibrationNotDetermined(
                f"the calibration is not determined by the data: sin^2 of the smallest principal angle between "
                f"its columns and the rest of the design is {lam[0]:.3g} (accepted: >= {MIN_SIN2_THETA:g})")
        amplification = 1.0 / math.sqrt(min(lam[0], 1.0))
        if base is None or (scalable and base_scale > 0.5 / amplification):
            base_scale = 0.5 / amplification
            base = solve(h, log, base_scale)
            if base.residuals is None:
                raise ValueError("solve(h, log, scale) must return the residuals of its solution")
            solutions.append(("data", base.history))
        c = np.linalg.solve(S, C.T @ base.residuals) if n else np.zeros(0)
        # error of x_0 - X c (in units of the tolerance) <= base_scale + col_scale sum |c| [mas]
        met = not scalable or col_scale * np.sum(np.abs(c)) <= 0.5 / amplification
        if met:
            break
        col_scale = 0.5 / (amplification * np.sum(np.abs(c))) * (1.0 - TIGHTENING_MARGIN)
    else:
        raise CalibrationNotDetermined(
            f"the calibration's solutions did not reach the asked accuracy in {MAX_ROUNDS} rounds (fitted "
            f"calibration {np.sum(np.abs(c)):.3g} mas in all, error amplification {amplification:.3g})")
    sol = dataclasses.replace(base)
    sol.x = base.x - sum((ck * sl.x for ck, sl in zip(c, sols)), np.zeros_like(base.x))
    sol.attitude = base.attitude - sum((ck * sl.attitude for ck, sl in zip(c, sols)), np.zeros_like(base.attitude))
    sol.residuals = base.residuals - R @ c
    sol.residual_rms = float(np.sqrt(np.mean(sol.residuals ** 2))) if sol.residuals.size else 0.0
    sol.history = [rec for _, hist in solutions for rec in hist]
    sol.converged = bool(base.converged and all(sl.converged for sl in sols))
    eig = np.linalg.eigvalsh(0.5 * (S + S.T)) if n else np.ones(1)
    return CalibratedSolution(solution=sol, c=c, solutions=solutions, condition=float(eig[-1] / eig[0]),
                              amplification=amplification)


def _generalized_eigvalsh(S, D) -> np.ndarray:
    """Eigenvalues of ``S`` relative to ``D`` (both symmetric, ``D`` positive definite),
    ascending: ``1 - cos^2`` of the principal angles between the calibration columns and
    the span of the stars' and attitude's design, in the metric of ``N``."""
    L = np.linalg.cholesky(D)
    Li = np.linalg.inv(L)
    return np.linalg.eigvalsh(Li @ S @ Li.T)
