"""A basic-angle variation solved with the stars and the attitude (a calibration AGIS solves).

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
measurement, so they are not put into the banded blocks of :mod:`.problem`: with ``A`` the
design of the stars and the attitude, ``A_c`` that of the calibration (normalised like the
measurements) and ``N`` the normal matrix of :mod:`.problem` (prior and frame included), the
bordered system

    [[N, G], [G', D]] [x; c] = [A' h; A_c' h],   G = A' A_c,  D = A_c' A_c,

is solved by the one PCG of :func:`.solve.solve_global` with ``border=A_c``: ``G`` is made
once, in the setup pass, as the right-hand side the columns would give as measurements
(its stars' rows stay with their chunks), so an iteration costs no further pass over the
measurements, only ``n_cal`` dot products and vector updates; the preconditioner treats
``c`` with ``D^-1``. The preconditioned bordered matrix differs from the unbordered one by
a matrix of rank at most ``2 n_cal``, so CG needs at most that many more iterations (in exact
arithmetic) to deal with it, however nearly degenerate the calibration is: measured, the
same iteration counts as without the calibration (``tests/solver/test_calibration.py``;
docs/notes/table3/candidate_calibration.md). The energy rule of :mod:`.stopping` then bounds the error of every estimated
quantity, the calibration and its correlations with the stars included, by the asked
fraction of its formal uncertainty in the bordered system.

The per-star covariances stay those of :mod:`.problem` (attitude and calibration as known),
as the paper's Table 3 evaluates them. How it was solved before the border:
docs/solver_design.md, "Calibration".
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..scanning.attitude import attitude_for

__all__ = ["BasicAngleColumns", "basic_angle_columns", "calibration_design", "CalibrationNotDetermined"]


class CalibrationNotDetermined(np.linalg.LinAlgError):
    """The calibration cannot be solved: some combination of its unknowns has no measurement
    (its columns' normal matrix ``D`` is singular to rounding: no AL measurement, or harmonics
    that the spin phases sampled cannot tell apart)."""


#: Largest condition number of ``D = A_c' A_c`` accepted (:func:`calibration_design`): a choice,
#: far above the experiment's (~1 for harmonics of a spin phase sampled all year round).
MAX_D_CONDITION = 1e12


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


def calibration_design(columns: BasicAngleColumns) -> np.ndarray:
    """The calibration's normalised partials ``A_c (m, n_cal)`` (:func:`.solve.solve_global`'s
    ``border``), checked to be determined by the measurements at all (module notes)."""
    C = np.column_stack([columns.column(k) for k in range(columns.n_cal)])
    eig = np.linalg.eigvalsh(C.T @ C)
    if not (eig[0] > 0 and eig[-1] <= MAX_D_CONDITION * eig[0]):
        raise CalibrationNotDetermined(
            f"{columns.n_cal} calibration unknowns are not determined by the measurements (condition number of "
            f"their normal matrix {eig[-1] / eig[0] if eig[0] > 0 else math.inf:.3g}, accepted: <= {MAX_D_CONDITION:g})")
    return C
